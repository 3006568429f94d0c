# brdfpipe: reference pipeline for measured-material research.
# Entry point only: rules live in workflow/rules/, code in src/brdfpipe/.

from snakemake.utils import min_version, validate

min_version("9.27")


configfile: "config/config.yaml"


validate(config, "workflow/schemas/config.schema.yaml", set_default=True)


include: "workflow/rules/common.smk"
include: "workflow/rules/data.smk"
include: "workflow/rules/acquisition.smk"
include: "workflow/rules/manifold.smk"
include: "workflow/rules/render.smk"


rule all:
    input:
        store=STORE,
        splits=SPLITS,
        pca=expand(f"{RESULTS}/svd/{{split}}.zarr", split=PCA_SPLITS),
        directions=direction_files("train") + direction_files("all"),
        evaluation=f"{RESULTS}/evaluation/errors.csv",
        consistency_all=f"{RESULTS}/evaluation/consistency-all.csv",
        figures=ACQUISITION_FIGURES,
        gplvm=expand(f"{RESULTS}/gplvm/q{{q}}.npz", q=MAN["latent_dims"]),
        manifold=MANIFOLD_DATA,
        manifold_figures=MANIFOLD_FIGURES,
        prerenders=expand(f"{RENDER_DIR}/materials/{{material}}.exr", material=MATERIALS),
        error_maps=f"{ERRORMAP_DIR}/summary.csv",
        render_figures=RENDER_FIGURES,
    default_target: True
