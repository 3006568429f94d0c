"""brdfpipe: a reference pipeline for measured-material (MERL BRDF) research.

Library modules are pure functions with no Snakemake in them:

* :mod:`brdfpipe.merl`  – the MERL ``.binary`` format, lookup and cell geometry;
* :mod:`brdfpipe.synth` – a synthetic, physically based MERL-format database;
* :mod:`brdfpipe.store` – the chunked Zarr store of the materials × cells matrix;
* :mod:`brdfpipe.cli`   – the ``brdfpipe`` command line.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("brdfpipe")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
