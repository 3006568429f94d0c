"""The registries: the names and records of what people add, light enough for parse time.

The bottom layer: the standard library and other registry modules only, no other part
of brdfpipe.  The planner (:mod:`brdfpipe.plan`), the workflow's wildcard
constraints, the config schema's enums (a test keeps them equal) and the
science modules all read the same records here, so a name is written once.

* :mod:`brdfpipe.registry.errors`      – :class:`ConfigError`, raised by every parse-time check (one line naming the key);
* :mod:`brdfpipe.registry.acquisition` – the acquisition set-ups (:class:`SetupKind`) and the optimiser's metrics;
* :mod:`brdfpipe.registry.nearfield`   – the near-field camera of Xu §5.2, shared by the acquisition geometry and the capture;
* :mod:`brdfpipe.registry.manifold`    – the manifold's data spaces (:class:`DataSpace`), GPLVM optimisers, Soler's paths;
* :mod:`brdfpipe.registry.tables`      – the columns of the CSV tables one stage writes and others (figures, claims) read;
* :mod:`brdfpipe.registry.layouts`     – the layout of a MERL folder and of a synthetic database folder;
* :mod:`brdfpipe.registry.figures`     – every figure of the three tracks (:class:`Figure`): stem, paper figure, caption, when a config draws it.
"""
