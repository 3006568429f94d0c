"""The acquisition track: minimal BRDF sampling after Xu et al. 2016.

Principal components of the log-mapped data, the expected reconstruction
error of a set of sampled cells, which cells an acquisition configuration
observes, the direction optimiser, reconstruction from sparse observations,
the leave-out evaluation of the direction sets and the track's figures.
Imports :mod:`brdfpipe.data` and :mod:`brdfpipe.core`.

* :mod:`brdfpipe.acquisition.svd`         – principal components of a log-map (eq. 1);
* :mod:`brdfpipe.acquisition.metrics`     – the expected error E(S) (eq. 15), condition number (eq. 6), eq. 4;
* :mod:`brdfpipe.acquisition.geometry`    – setups and the MERL cells a configuration observes;
* :mod:`brdfpipe.acquisition.optimize`    – the greedy few-to-many optimiser (§5.1) and directions files;
* :mod:`brdfpipe.acquisition.candidates`  – the optimiser's candidates: a set-up's configurations, their metric keys;
* :mod:`brdfpipe.acquisition.paper_directions` – the near-field directions §6 states in words, with their E(S);
* :mod:`brdfpipe.acquisition.reconstruct` – a full BRDF reconstructed from sparse observations (eq. 4), and a
  held-out material from direction sets (Xu Figs. 2, 15);
* :mod:`brdfpipe.acquisition.evaluation`  – leave-out evaluation (errors.csv), consistency check, training-size curve;
* :mod:`brdfpipe.acquisition.closedloop`  – reconstruction from captured images next to the table lookup (issue 13);
* :mod:`brdfpipe.acquisition.unseen`      – materials of other databases reconstructed with the run's model (issue 22);
* :mod:`brdfpipe.acquisition.figures`     – the Xu et al. 2016 figure analogues (re-exports the three below);
* :mod:`brdfpipe.acquisition.figure_inputs` – errors.csv and training_size.csv as the figures read them;
* :mod:`brdfpipe.acquisition.figures_configs` – Figs. 8, 9, 14: the chosen light/camera configurations;
* :mod:`brdfpipe.acquisition.figures_recon` – Figs. 2, 15: renders of reconstructed held-out materials;
* :mod:`brdfpipe.acquisition.realism`     – how a database compares with another: PCA spectrum, held-out
  PCA-k error, albedo and specular-width distributions (issue 22: synthetic against merl-nbrdf).
"""
