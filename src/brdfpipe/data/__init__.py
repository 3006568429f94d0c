"""Stage 1 of the pipeline: the measured-material data every track starts from.

MERL files (real, evaluated from published neural fits, or synthetic) are read, assembled into one chunked
materials × cells store, and mapped to the log-relative space of Xu et al.
2016 (which the GPLVM's ``logrel`` data space of :mod:`brdfpipe.manifold`
reuses).  Imports only :mod:`brdfpipe.core`.

* :mod:`brdfpipe.data.merl`     – the MERL ``.binary`` format, lookup and cell geometry;
* :mod:`brdfpipe.data.provenance` – provenance marks: measured, synthetic or derived, and from what;
* :mod:`brdfpipe.data.nbrdf`    – published neural fits of measured materials (Sztrajman et al. 2021) on the MERL grid;
* :mod:`brdfpipe.data.synth`    – a synthetic, physically based MERL-format database;
* :mod:`brdfpipe.data.synthmodel` – the analytic BRDF models of its five families;
* :mod:`brdfpipe.data.databases` – the registry of databases a run can use, and their labels and titles;
* :mod:`brdfpipe.data.database` – which database a run uses (fits, a folder of MERL files, or synthetic);
* :mod:`brdfpipe.data.store`    – the chunked Zarr store of the materials × cells matrix: opening, checking, reading;
* :mod:`brdfpipe.data.ingest`   – writing that store: a row store per material, then their assembly;
* :mod:`brdfpipe.data.logmap`   – the log-relative mapping of that matrix.
"""
