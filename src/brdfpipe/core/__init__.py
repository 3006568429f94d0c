"""Shared infrastructure at the bottom of the library: no science, no stage.

Every other subpackage may import these modules; they import nothing of
``brdfpipe`` above ``brdfpipe.core`` but the specs (:mod:`brdfpipe.registry`) (``tests/test_layout.py`` checks it).
The light ones (:mod:`~brdfpipe.core.filenames`, :mod:`~brdfpipe.core.stamps`,
:mod:`~brdfpipe.core.version`) are imported by the Snakefile at parse time,
so this ``__init__`` imports nothing.  What the workflow plans from its
configuration is the planner's (:mod:`brdfpipe.plan`, on top).

* :mod:`brdfpipe.core.atomic`    – atomic outputs (temporary sibling, then rename), the job lease;
* :mod:`brdfpipe.core.command`   – the error contract of the ``python -m brdfpipe.…`` command lines;
* :mod:`brdfpipe.core.exr`       – OpenEXR images that are data (renders, blends, error maps);
* :mod:`brdfpipe.core.filenames` – every file name of the workflow's DAG (and the rule that writes it);
* :mod:`brdfpipe.core.integrity` – digests of every intermediate, written by its writer, checked by its readers;
* :mod:`brdfpipe.core.logutil`   – logging set-up of the command line and the workflow scripts;
* :mod:`brdfpipe.core.notes`     – a figure's note: the run's numbers its report caption quotes;
* :mod:`brdfpipe.core.plot`      – figure helpers shared by every track (style, inputs, atomic saving);
* :mod:`brdfpipe.core.resources` – the machine's memory and free disk, for bounds checked before work starts;
* :mod:`brdfpipe.core.stamps`    – job stamps: what defines each job, for reruns whatever Snakemake's records say;
* :mod:`brdfpipe.core.threads`   – the BLAS threads of a job (its rule's declared threads);
* :mod:`brdfpipe.core.version`   – content digests of the library's source (provenance, reruns);
* :mod:`brdfpipe.core.zgroup`    – opening finished brdfpipe Zarr groups.
"""
