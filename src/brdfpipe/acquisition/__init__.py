"""The acquisition track: minimal BRDF sampling after Xu et al. 2016.

Principal components of the log-mapped data, the expected reconstruction
error of a set of sampled cells, which cells an acquisition configuration
observes, the direction optimiser, reconstruction from sparse observations
and the track's figures.  Imports :mod:`brdfpipe.data` and :mod:`brdfpipe.core`.

* :mod:`brdfpipe.acquisition.svd`         – principal components of a log-map (eq. 1);
* :mod:`brdfpipe.acquisition.reconstruct` – reconstruction from sparse observations, leave-out evaluation.
"""
