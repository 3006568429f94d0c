"""Specs: the names and records of what people add, light enough for parse time.

The bottom layer: the standard library and other specs only, no other part
of brdfpipe.  The planner (:mod:`brdfpipe.plan`), the workflow's wildcard
constraints, the config schema's enums (a test keeps them equal) and the
science modules all read the same records here, so a name is written once.

* :mod:`brdfpipe.spec.errors`      – :class:`ConfigError`, raised by every parse-time check (one line naming the key);
* :mod:`brdfpipe.spec.acquisition` – the acquisition set-ups (:class:`SetupKind`) and the optimiser's metrics;
* :mod:`brdfpipe.spec.nearfield`   – the near-field camera of Xu §5.2, shared by the acquisition geometry and the capture;
* :mod:`brdfpipe.spec.manifold`    – the manifold's data spaces (:class:`DataSpace`), GPLVM optimisers, Soler's paths;
* :mod:`brdfpipe.spec.tables`      – the columns of the CSV tables one stage writes and others (figures, claims) read;
* :mod:`brdfpipe.spec.layouts`     – the layout of a MERL folder and of a synthetic database folder;
* :mod:`brdfpipe.spec.figures`     – every figure of the three tracks (:class:`Figure`): stem, paper figure, caption, when a config draws it.
"""
