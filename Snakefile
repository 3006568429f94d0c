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
        store=fn.store(),
        splits=fn.splits(),
        pca=expand(fn.svd_model("{split}"), split=PCA_SPLITS),
        directions=DIRECTIONS["train"] + DIRECTIONS["all"],
        evaluation=fn.errors(),
        consistency=expand(fn.consistency("{split}"), split=CHECKED_SPLITS),
        training_size=fn.training_size() if CURVE_DIRECTIONS else [],
        figures=flat(ACQUISITION_FIGURES),
        gplvm=expand(fn.gplvm_model("{q}"), q=MAN["latent_dims"]),
        manifold=MANIFOLD_DATA,
        manifold_figures=flat(MANIFOLD_FIGURES),
        prerenders=expand(fn.prerender(SCENE, "{material}"), material=MATERIALS),
        error_maps=fn.errormap_summary(SCENE) if PATH_POINTS else [],
        render_figures=flat(RENDER_FIGURES),
    default_target: True
