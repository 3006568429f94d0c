"""The manifold track: GPLVM material manifolds after Soler et al. 2018.

Fitting the GPLVM, exploring and analysing its latent space, measuring how
faithful it is per data space, and the track's figures.  Imports
:mod:`brdfpipe.data`, :mod:`brdfpipe.core` and :mod:`brdfpipe.registry`.

* :mod:`brdfpipe.manifold.spaces`     – the data spaces' maps (forward map of a block, per-cell maps);
* :mod:`brdfpipe.manifold.gram`       – the Gram matrices of the materials in a data space, streamed from the store,
  and their file;
* :mod:`brdfpipe.manifold.likelihood` – the GPLVM's kernel and likelihood (eqs. 5–6) and their derivatives;
* :mod:`brdfpipe.manifold.fitting`    – fitting the GPLVM: the start, the optimisers, the record of a fit;
* :mod:`brdfpipe.manifold.newton`     – the ``newton`` optimiser (the same maximum on every BLAS kernel);
* :mod:`brdfpipe.manifold.hookejeeves` – the paper's direct search (methods ``hooke-jeeves``, ``hybrid``);
* :mod:`brdfpipe.manifold.gplvm`      – the fitted GPLVM (§2.1–§3): its model file and the interpolation;
* :mod:`brdfpipe.manifold.latent`     – the latent space: hull, neighbours, extrapolation, sampling;
* :mod:`brdfpipe.manifold.perceptual` – perceptual BRDF distance (Pereira & Rusinkiewicz 2012);
* :mod:`brdfpipe.manifold.fidelity`   – how faithful a manifold is, per data space (§3–§5);
* :mod:`brdfpipe.manifold.albedo`     – the white-sky albedo of materials (§4.2);
* :mod:`brdfpipe.manifold.blendpass`  – albedo and perceptual distances of many blends in one pass over the store;
* :mod:`brdfpipe.manifold.analysis`   – analyses of a fitted manifold (§4, Figs. 7–10);
* :mod:`brdfpipe.manifold.derivation` – the provenance marks of the materials it blends;
* :mod:`brdfpipe.manifold.unseen`     – materials outside the training set: latent position x*, reproduction;
* :mod:`brdfpipe.manifold.samples`    – materials at random latent points, written for rendering (Fig. 1);
* :mod:`brdfpipe.manifold.lengthscale` – the interpolant and the eq. 7 bound as the length scale shrinks (Fig. 6);
* :mod:`brdfpipe.manifold.figures`    – the Soler et al. 2018 figure analogues;
* :mod:`brdfpipe.manifold.figure_inputs` – the figures' inputs, read and checked;
* :mod:`brdfpipe.manifold.latent_map` – the latent maps' zoomed views and point names;
* :mod:`brdfpipe.manifold.lengthscale_figure` – Fig. 6, drawn for :mod:`~brdfpipe.manifold.figures`.
"""
