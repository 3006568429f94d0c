"""brdfpipe: a reference pipeline for measured-material (MERL BRDF) research.

Library modules are pure functions with no Snakemake in them:

* :mod:`brdfpipe.data.merl`  – the MERL ``.binary`` format, lookup and cell geometry;
* :mod:`brdfpipe.data.synth` – a synthetic, physically based MERL-format database;
* :mod:`brdfpipe.data.store` – the chunked Zarr store of the materials × cells matrix;
* :mod:`brdfpipe.cli`   – the ``brdfpipe`` command line.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
