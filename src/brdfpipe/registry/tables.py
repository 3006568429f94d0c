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
Xu Fig. 8's table (``fig08-*.csv``)       :mod:`brdfpipe.acquisition.figures_configs`                  claims
``evaluation/paper-directions.csv``       :mod:`brdfpipe.acquisition.paper_directions`                 claims
Xu Figs. 9, 14 (``fig09-*.csv``, …)       :mod:`brdfpipe.acquisition.figures_configs`                  tests, users
Xu Fig. 3's table (``fig03-*.csv``)       :mod:`brdfpipe.acquisition.figures`                          tests, users
Xu Figs. 2, 15 (``fig02-*.csv``, …)       :mod:`brdfpipe.acquisition.figures_recon`                    tests, users
a GPLVM fit's ``trace.csv``               :func:`brdfpipe.manifold.gplvm.write_trace`                  figures, claims
``results/manifold/albedo.csv``           :mod:`brdfpipe.manifold.analysis`                            figures
``results/manifold/paths.csv``            :mod:`brdfpipe.manifold.analysis`                            figures, claims
``results/manifold/lengthscales.csv``     :mod:`brdfpipe.manifold.lengthscale`                         figures
``results/manifold/reproduction.csv``     :mod:`brdfpipe.manifold.analysis`                            figures, claims
``results/manifold/spaces.csv``           :mod:`brdfpipe.manifold.fidelity`                            figures, claims
``results/manifold/stability.csv``        :mod:`brdfpipe.manifold.fidelity`                            figures
``results/unseen/<db>-albedo.csv``        :mod:`brdfpipe.data.nbrdf`                                   claims
``renders/<scene>/bounce-shares.csv``     :func:`brdfpipe.rendering.blend.bounce_shares`               claims
``results/errormaps/<scene>/summary.csv``  :func:`brdfpipe.rendering.blend.error_maps`                 figures, claims
the noise floor's ``floor-check.csv``     :func:`brdfpipe.rendering.blend.floor_check_table`           figures, claims
========================================  ===========================================================  ===============
"""

from __future__ import annotations

__all__ = [
    "ERRORS",
    "TRAINING_SIZE",
    "UNSEEN_ERRORS",
    "MANIFOLD_UNSEEN",
    "FIG08",
    "PAPER_DIRECTIONS",
    "CONFIGURATIONS",
    "RECON_VS_DEVIATION",
    "RECONSTRUCTION_PANELS",
    "GPLVM_TRACE",
    "MATERIAL_ALBEDO",
    "LATENT_PATHS",
    "LENGTHSCALES",
    "REPRODUCTION",
    "SPACES",
    "STABILITY",
    "FIT_ALBEDO",
    "BOUNCE_SHARES",
    "ERROR_MAP_SUMMARY",
    "FLOOR_CHECK",
    "columns",
]

#: ``errors.csv``: one value per (split, setup, fov, metric, n, material, channel, kind) of a database.
ERRORS: tuple[str, ...] = ("database", "split", "setup", "fov", "metric", "n", "material", "channel", "kind", "value")
#: ``training_size.csv``: the error of 2-image near-field acquisition vs the number of training materials.
TRAINING_SIZE: tuple[str, ...] = ("database", "n_train", "order_seed", "material", "channel", "kind", "value")
#: The acquisition's ``unseen.csv``: the columns of ``errors.csv`` with the model's database after ``database``.
UNSEEN_ERRORS: tuple[str, ...] = (ERRORS[0], "model_database", *ERRORS[1:])
#: The manifold's ``unseen.csv``: one row per unseen material and method of finding its latent position.
MANIFOLD_UNSEEN: tuple[str, ...] = ("database", "model_database", "space", "material", "method", "k",
                                    "relative_error", "log_likelihood", "nearest", "latent")
#: Xu Fig. 8's table: per FOV and set size, each image's angles, light and camera directions and E(S).
FIG08: tuple[str, ...] = (
    "fov_deg", "n_images", "image", "theta_h_deg", "theta_d_deg", "phi_d_deg",
    "light_theta_deg", "light_phi_deg", "camera_theta_deg", "camera_phi_deg",
    "expected_error", "split", "database",
)
#: The near-field directions Xu §6 states in words, evaluated (``paper-directions.csv``): one row per image of
#: each direction's set (``chosen_by``: ``sentence`` or ``optimiser``), the set's E(S) and how many configurations
#: match the sentence and were evaluated.
PAPER_DIRECTIONS: tuple[str, ...] = (
    "database", "split", "direction", "fov_deg", "grid", "n_images", "image", "chosen_by",
    "theta_h_deg", "theta_d_deg", "phi_d_deg", "light_theta_deg", "expected_error", "matching", "evaluated",
)
#: Xu Figs. 9 and 14: each image of a chosen set, in in-out (light θi, φi; camera θo, φo) and Rusinkiewicz angles.
CONFIGURATIONS: tuple[str, ...] = (
    "setup", "fov_deg", "n_images", "image", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg",
    "theta_h_deg", "theta_d_deg", "phi_d_deg", "expected_error", "split", "database",
)
#: Xu Fig. 3: per material and direction set E_recon (eq. 12) and E_deviation (eq. 9), RMS over the cells.
RECON_VS_DEVIATION: tuple[str, ...] = (
    "database", "material", "setup", "fov", "metric", "n", "e_recon", "e_deviation", "rms_log",
)
#: Xu Figs. 2 and 15: every image panel (input, reconstruction, reference) of every material's row.
RECONSTRUCTION_PANELS: tuple[str, ...] = (
    "database", "material", "column", "kind", "setup", "fov", "metric", "n", "image", "file", "rms_log",
    "render_relative_rmse",
)
#: A GPLVM fit's log-likelihood trace.
GPLVM_TRACE: tuple[str, ...] = ("step", "stage", "log_likelihood")
#: The training materials' albedo (``albedo.csv``).
MATERIAL_ALBEDO: tuple[str, ...] = ("database", "material", "r", "g", "b", "luminance")
#: One row per point of each latent path (``paths.csv``).
LATENT_PATHS: tuple[str, ...] = (
    "database", "space", "q", "path", "material_a", "material_b", "step", "t", "latent_distance",
    "perceptual_a", "perceptual_b", "perceptual_ab", "nearest", "deviation", "bound",
)
#: The interpolant and the eq. 7 bound along one latent path per length scale (``lengthscales.csv``, Soler Fig. 6).
LENGTHSCALES: tuple[str, ...] = (
    "database", "space", "q", "path", "material_a", "material_b", "ell_factor", "ell", "kappa", "t", "nearest",
    "latent_distance_nearest", "deviation", "bound", "from_mean", "sum_abs_w", "z_norm",
)
#: Each material's reproduction error by the GPLVM and by PCA (``reproduction.csv``).
REPRODUCTION: tuple[str, ...] = ("database", "space", "material", "method", "k", "relative_error")
#: One row per GPLVM candidate and latent dimension (``spaces.csv``): how the candidate is fitted
#: (``normalise``, ``method``, ``init``), the albedo of the *clamped* interpolated table (what a renderer
#: receives; ``albedo_clamped_*``) and of the unclamped one (``albedo_bad_*``, Σ wᵢ Aᵢ), the table's jump next to
#: each material towards its nearest neighbour (``jump_nn_*``, raw units) and its reproduction at the material;
#: :mod:`brdfpipe.manifold.fidelity` defines each.
SPACES: tuple[str, ...] = (
    "database", "candidate", "space", "mu", "normalise", "method", "init", "q", "default",
    "log_likelihood", "log_likelihood_eq6", "kappa",
    "albedo_clamped_bad_hull", "albedo_clamped_bad_map", "albedo_clamped_points",
    "albedo_bad_hull", "albedo_bad_map", "hull_points",
    "sum_abs_w_hull_median", "sum_abs_w_hull_max", "sum_abs_w_path_median", "sum_abs_w_path_max",
    "jump_nn_median_1e-6", "jump_nn_p90_1e-6", "jump_nn_max_1e-6", "jump_nn_worst", "reproduction_max",
    "stability_raw_median_1e-6", "stability_raw_p90_1e-6", "stability_space_median_1e-6",
    "stability_space_p90_1e-6",
    "nn_median", "nn_min", "pairs_within_sqrt2mu", "pairs_within_1e-5",
    "perceptual_max_deviation", "perceptual_decreasing_steps",
)
#: The interpolant's stability under perturbations, per candidate, norm and ε (``stability.csv``).
STABILITY: tuple[str, ...] = ("database", "candidate", "space", "mu", "q", "norm", "epsilon", "median", "p90", "max")
#: Directional albedo of a database of fits' tables (``<database>-albedo.csv``).
FIT_ALBEDO: tuple[str, ...] = ("database", "material", "theta_i_deg", "r", "g", "b", "luminance")
#: The I²⁺ share of each pre-render (``bounce-shares.csv``).
BOUNCE_SHARES: tuple[str, ...] = (
    "database", "material", "mean_image", "mean_one", "share_image", "mean_image_object", "mean_one_object",
    "share_object", "object_pixels",
)


#: One row per rendered path point (``summary.csv``): blend of pre-renders against the reference render
#: (``ratio*``), its ``I¹⁻`` parts (``*_one*``), Σ|wᵢ| and the share of the interpolated table the reference
#: clamps, and the blend against a reference that differs from it only by the L²⁺ paths
#: (``ratio_isolated_seed2``: :func:`brdfpipe.rendering.blend.error_maps` says how it is formed).
ERROR_MAP_SUMMARY: tuple[str, ...] = (
    "database", "path", "t", "rmse_blend", "rmse_noise", "ratio", "rmse_blend_seed2", "ratio_seed2", "mean_reference",
    "rmse_blend_one", "rmse_noise_one", "ratio_one", "rmse_blend_one_seed2", "ratio_one_seed2", "mean_reference_one",
    "ratio_seed2_se", "ratio_one_seed2_se", "sum_abs_w", "clamped_fraction",
    "ratio_isolated_seed2", "ratio_isolated_seed2_se",
)
#: Every floor-checked candidate's blends against the noise floor, one row per path point (``floor-check.csv``).
FLOOR_CHECK: tuple[str, ...] = (
    "database", "candidate", "space", "mu", "default", "path", "t", "width", "height", "spp",
    "sum_abs_w", "norm2_w", "clamped_fraction",
    "rmse_noise", "ratio", "ratio_seed2", "rmse_noise_one", "ratio_one", "ratio_one_seed2",
    "ratio_seed2_se", "ratio_one_seed2_se", "ratio_isolated_seed2", "ratio_isolated_seed2_se",
)


def columns(table: tuple[str, ...], *names: str) -> tuple[str, ...]:
    """``names``, the columns of ``table`` a reader needs (a reader may need fewer than the writer writes).

    ValueError naming the column if one is not the table's: a reader's
    columns are checked against their owner where the reader names them.
    """
    unknown = [n for n in names if n not in table]
    if unknown:
        raise ValueError(f"column(s) {', '.join(unknown)} not in the table ({', '.join(table)})")
    return names
