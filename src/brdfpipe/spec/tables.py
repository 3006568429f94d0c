"""The columns of the CSV tables one stage writes and others read: one declaration each.

The writer writes these columns in this order; every reader (the figures,
the claims, the next stage) requires them.  The files themselves are
written and read through :func:`brdfpipe.core.integrity.write_csv` /
:func:`~brdfpipe.core.integrity.read_csv_text` (a digest line first, checked by
every reader).  Standard library only: the report reads them too.

========================================  ===========================================================  ===============
table                                     writer                                                       readers
========================================  ===========================================================  ===============
``results/evaluation/errors.csv``         :func:`brdfpipe.acquisition.evaluation.write_errors`         figures, claims
``results/evaluation/training_size.csv``  :func:`brdfpipe.acquisition.evaluation.training_size_curve`  figures, claims
``results/evaluation/unseen.csv``         :mod:`brdfpipe.acquisition.unseen`                           figures, claims
``results/manifold/unseen.csv``           :mod:`brdfpipe.manifold.unseen`                              figures
========================================  ===========================================================  ===============
"""

from __future__ import annotations

__all__ = ["ERRORS", "TRAINING_SIZE", "UNSEEN_ERRORS", "MANIFOLD_UNSEEN"]

#: ``errors.csv``: one value per (split, setup, fov, metric, n, material, channel, kind) of a database.
ERRORS: tuple[str, ...] = ("database", "split", "setup", "fov", "metric", "n", "material", "channel", "kind", "value")
#: ``training_size.csv``: the error of 2-image near-field acquisition vs the number of training materials.
TRAINING_SIZE: tuple[str, ...] = ("database", "n_train", "order_seed", "material", "channel", "kind", "value")
#: The acquisition's ``unseen.csv``: the columns of ``errors.csv`` with the model's database after ``database``.
UNSEEN_ERRORS: tuple[str, ...] = (ERRORS[0], "model_database", *ERRORS[1:])
#: The manifold's ``unseen.csv``: one row per unseen material and method of finding its latent position.
MANIFOLD_UNSEEN: tuple[str, ...] = ("database", "model_database", "space", "material", "method", "k",
                                    "relative_error", "log_likelihood", "nearest", "latent")
