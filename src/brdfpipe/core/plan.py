"""What the workflow plans from its configuration, decided before any job runs.

Everything a Snakefile needs to know at parse time and that could otherwise
fail in the middle of a run lives here, as plain functions that the tests
call directly: checks of the values a JSON schema cannot express (finite
numbers, sizes that fit the data, latent dimensions below the number of
materials), the latent paths, and which direction sets, evaluation outputs
and figures a configuration produces.  A configuration that passes
:func:`check_config` builds a DAG whose every declared output some job
writes.

Light: the standard library only (NumPy is imported inside
:func:`default_paths`, the one seeded choice).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from brdfpipe.core import filenames
from brdfpipe.spec.acquisition import FIXED_SETUPS, setup_fovs
from brdfpipe.spec import figures as figure_specs
from brdfpipe.spec.manifold import SOLER_PATHS, candidate_label

__all__ = [
    "ConfigError",
    "config_key",
    "schema_problem",
    "describe_schema_error",
    "SOLER_PATHS",
    "candidate_label",
    "manifold_candidates",
    "check_finite",
    "check_config",
    "default_paths",
    "check_paths",
    "latent_paths",
    "path_q",
    "direction_files",
    "curve_directions",
    "training_sizes",
    "albedo_map_dims",
    "acquisition_figures",
    "manifold_figures",
    "render_figures",
    "floor_check_candidates",
    "closedloop_directions",
    "check_closed_loop",
    "unseen_directions",
    "unseen_figures",
    "unseen_map_q",
    "UNSEEN_RULES",
    "sensor_max_snr",
    "MEMORY_MB",
    "JOB_MEMORY_LIMIT_MB",
    "MEASURED_SIZES",
    "SIZE_MEMORY_MB",
    "job_sizes",
    "model_mb",
    "mem_mb",
    "planned_rules",
    "check_memory",
]

#: Mitsuba renders at most 2^32 − 1 samples in one pass (its wavefront index is 32-bit; 3.9's own split of a
#: larger render fails).
MITSUBA_MAX_SAMPLES: int = 2**32


class ConfigError(ValueError):
    """A configuration value is unusable; the message names the key."""


def config_key(path: Sequence[Any]) -> str:
    """``["render", "resolution", 0]`` → ``"render.resolution[0]"``: a key path as a user writes it."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _shown(value: Any, limit: int = 60) -> str:
    text = f"{value:.10g}" if isinstance(value, float) else repr(value)
    return text if len(text) <= limit else text[: limit - 5] + " …" + text[-3:]


_JSON_TYPES = {
    "integer": "an integer", "number": "a number", "string": "a string", "array": "a list",
    "object": "a mapping (key: value)", "null": "null", "boolean": "true or false",
}


def describe_schema_error(error: Any) -> str:
    """One line for a JSON-schema violation: the key path (``render.spp``), the value and what is wrong.

    ``error`` is a ``jsonschema.ValidationError`` (duck-typed: ``absolute_path``,
    ``validator``, ``validator_value``, ``instance``, ``schema``,
    ``message``).  A schema may give the reason of a limit in a keyword
    ``x-reason`` next to it; it ends the line.
    """
    import difflib

    path = list(error.absolute_path)
    key = config_key(path)
    where = f"config {key}" if key else "config"
    kind, limit, value = error.validator, error.validator_value, error.instance
    sub = error.schema if isinstance(error.schema, Mapping) else {}
    reason = sub.get("x-reason")
    why = f" ({reason})" if reason else ""
    if kind == "additionalProperties" and isinstance(value, Mapping):
        allowed = list(sub.get("properties", {}))
        unknown = sorted((str(k) for k in value if k not in allowed), key=str)
        first = unknown[0] if unknown else "?"
        guess = difflib.get_close_matches(first, allowed, n=1)
        hint = f"did you mean {guess[0]!r}? " if guess else ""
        more = f" (and {', '.join(unknown[1:])})" if len(unknown) > 1 else ""
        section = f"{key} has" if key else "top-level keys are"
        return (f"config {config_key([*path, first])}: unknown key{more}; {hint}{section}: "
                f"{', '.join(allowed)}")
    if kind == "type":
        types = [limit] if isinstance(limit, str) else list(limit)
        return f"{where} = {_shown(value)}: must be " + " or ".join(_JSON_TYPES.get(t, t) for t in types)
    if kind == "enum":
        return f"{where} = {_shown(value)}: must be one of " + ", ".join(str(v) for v in limit)
    if kind == "const":
        return f"{where} = {_shown(value)}: must be {limit!r}"
    bounds = {"minimum": "≥", "maximum": "≤", "exclusiveMinimum": ">", "exclusiveMaximum": "<"}
    if kind in bounds:
        return f"{where} = {_shown(value)}: must be {bounds[kind]} {_shown(limit)}{why}"
    if kind == "minItems":
        what = "must not be empty" if limit == 1 else f"needs at least {limit} entries (has {len(value)})"
        return f"{where}: {what}"
    if kind == "maxItems":
        return f"{where}: at most {limit} entries (has {len(value)}){why}"
    if kind == "uniqueItems":
        seen: list[Any] = []
        dup = next((v for v in value if v in seen or seen.append(v)), None)  # type: ignore[func-returns-value]
        return f"{where}: {_shown(dup)} is listed more than once"
    if kind == "required":
        missing = [k for k in limit if not (isinstance(value, Mapping) and k in value)]
        return f"{where}: missing key {', '.join(missing)}"
    if kind == "minLength":
        return f"{where}: must not be empty" if limit == 1 else f"{where} = {_shown(value)}: at least {limit} characters"
    if kind == "maxLength":
        return f"{where}: at most {limit} characters (has {len(value)}){why}"
    if kind == "pattern":
        meaning = sub.get("x-pattern") or f"match the pattern {limit}"
        return f"{where} = {_shown(value)}: must {meaning}"
    text = " ".join(str(error.message).split())
    return f"{where}: {text[:200]}"


def schema_problem(config: Mapping[str, Any], schema: Mapping[str, Any]) -> str | None:
    """The first violation of ``schema`` (a JSON schema, as a dict) by ``config`` as one line, or None.

    The line names the key path and what is wrong
    (:func:`describe_schema_error`), and how many other violations there
    are; the workflow stops with it instead of Snakemake's dump of the schema.
    Imports ``jsonschema`` (Snakemake's own validator) when called.
    """
    import jsonschema

    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(validator.iter_errors(config), key=lambda e: [str(p) for p in e.absolute_path])
    if not errors:
        return None
    best = jsonschema.exceptions.best_match(errors)
    line = describe_schema_error(best)
    more = len(errors) - 1
    return line + (f" (and {more} more problem{'s' if more > 1 else ''} after it)" if more else "")


def check_finite(value: Any, key: str = "") -> None:
    """Raise :class:`ConfigError` naming the first non-finite number (NaN, ±inf) anywhere in ``value``."""
    if isinstance(value, bool):
        return
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ConfigError(f"config {key or 'value'} = {value}: must be a finite number")
    elif isinstance(value, Mapping):
        for k, v in value.items():
            check_finite(v, f"{key}.{k}" if key else str(k))
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            check_finite(v, f"{key}[{i}]")


def path_q(manifold: Mapping[str, Any]) -> int:
    """The latent dimension whose model the paths and the rendering track use."""
    dims = [int(q) for q in manifold["latent_dims"]]
    q = max(dims) if manifold.get("path_q") is None else int(manifold["path_q"])
    if q not in dims:
        raise ConfigError(f"config manifold.path_q = {q} is not one of manifold.latent_dims {dims}")
    return q


def manifold_candidates(manifold: Mapping[str, Any]) -> dict[str, tuple[str, float]]:
    """Label → (space, μ) of every GPLVM candidate: the default (``space``, ``mu``) first, then ``candidates``.

    :class:`ConfigError` naming ``manifold.candidates`` for two entries with the same label.
    """
    out = {candidate_label(manifold["space"], manifold["mu"]): (str(manifold["space"]), float(manifold["mu"]))}
    seen: set[str] = set()
    for k, c in enumerate(manifold.get("candidates") or []):
        label = candidate_label(c["space"], c["mu"])
        if label in seen:
            raise ConfigError(f"config manifold.candidates[{k}]: {label} is listed twice")
        seen.add(label)
        have = out.setdefault(label, (str(c["space"]), float(c["mu"])))
        if have != (str(c["space"]), float(c["mu"])):
            raise ConfigError(
                f"config manifold.candidates[{k}]: mu = {c['mu']!r} differs from manifold.mu = {manifold['mu']!r} only "
                f"past 6 significant digits, so both would be {label}; use the same value or distinct ones"
            )
    return out


def training_sizes(acquisition: Mapping[str, Any], n_train: int) -> list[int]:
    """``acquisition.training_sizes``, checked against the number of training materials."""
    sizes = [int(n) for n in acquisition["training_sizes"]]
    too_big = [n for n in sizes if n > n_train]
    if too_big:
        raise ConfigError(
            f"config acquisition.training_sizes: {too_big} exceed the {n_train} training materials "
            "(all materials minus test_materials); use sizes up to that number"
        )
    return sizes


def check_config(config: Mapping[str, Any], *, materials: Sequence[str], train: Sequence[str]) -> None:
    """Every parse-time check of a schema-valid config against its database.

    Raises :class:`ConfigError` naming the key: non-finite numbers,
    ``training_sizes`` larger than the training set, latent dimensions not
    below the number of materials, a ``path_q`` without a model, equal render
    seeds, and bad latent paths.
    """
    check_finite(dict(config))
    n = len(materials)
    dims = [int(q) for q in config["manifold"]["latent_dims"]]
    bad = [q for q in dims if q >= n]
    if bad:
        raise ConfigError(
            f"config manifold.latent_dims: q = {bad} must be below the number of materials ({n})"
        )
    path_q(config["manifold"])
    manifold_candidates(config["manifold"])
    training_sizes(config["acquisition"], len(train))
    render = config["render"]
    if render["noise_seed"] == render["seed"]:
        raise ConfigError("config render.noise_seed must differ from render.seed (it measures the noise floor)")
    latent_paths(config["manifold"], materials)
    check_closed_loop(config)
    tags = [filenames.format_t(t) for t in render["path_points"]]
    dup = sorted({t for t in tags if tags.count(t) > 1})
    if dup:
        raise ConfigError(
            f"config render.path_points: values that differ only past 6 significant digits share a file name "
            f"(t = {', '.join(dup)}); give distinct values"
        )


def default_paths(materials: Sequence[str], seed: int, count: int = 3) -> list[tuple[str, str]]:
    """Soler Fig. 9's pairs when all of them are in ``materials``; else ``count`` seeded disjoint pairs."""
    names = sorted(materials)
    if all(m in names for pair in SOLER_PATHS for m in pair):
        return [tuple(p) for p in SOLER_PATHS]  # type: ignore[misc]
    if len(names) < 2:
        raise ConfigError("a latent path needs at least two materials")
    import numpy as np

    rng = np.random.default_rng(seed)
    k = min(count, len(names) // 2)
    pick = rng.choice(len(names), size=2 * k, replace=False)
    return [(names[pick[2 * i]], names[pick[2 * i + 1]]) for i in range(k)]


def check_paths(
    paths: Sequence[Sequence[str]], materials: Sequence[str], what: str = "manifold.paths"
) -> list[tuple[str, str]]:
    """Validate ``[[A, B], …]`` against the material list; :class:`ConfigError` naming the bad entry."""
    known = set(materials)
    out: list[tuple[str, str]] = []
    for k, pair in enumerate(paths):
        if isinstance(pair, str) or len(pair) != 2:
            raise ConfigError(f"{what}[{k}] must be a pair of material names, got {pair!r}")
        a, b = (str(m) for m in pair)
        for m in (a, b):
            if m not in known:
                raise ConfigError(f"{what}[{k}]: unknown material {m!r} (not in the database)")
        if a == b:
            raise ConfigError(f"{what}[{k}]: a path needs two different materials, got {a!r} twice")
        out.append((a, b))
    names = [filenames.path_name(a, b) for a, b in out]
    for k, name in enumerate(names):
        j = names.index(name)
        if j < k:
            if out[j] == out[k]:
                raise ConfigError(f"{what}: listed more than once: {name}")
            raise ConfigError(f"{what}[{j}] {list(out[j])} and [{k}] {list(out[k])} share the file name {name}; "
                              "rename a material or drop one path")
    return out


def latent_paths(manifold: Mapping[str, Any], materials: Sequence[str]) -> list[tuple[str, str]]:
    """The configured latent paths (``manifold.paths``), else :func:`default_paths` (seeded)."""
    if manifold.get("paths"):
        return check_paths(manifold["paths"], materials)
    return default_paths(materials, int(manifold["seed"]))


def direction_files(acquisition: Mapping[str, Any], split: str) -> list[str]:
    """Direction sets optimised on a split.

    ``train``: every setup × FOV × metric (they are evaluated); ``all``: only
    the near-field sets of the error metric (the paper's table of optimal
    configurations, Xu Fig. 8).
    """
    files = []
    for setup in acquisition["setups"]:
        if split == "all" and setup != "nearfield":
            continue
        fovs = setup_fovs(setup, acquisition["fovs"], acquisition["fixed_fov"])
        metrics = acquisition["metrics"] if split == "train" else ["error"]
        files += [filenames.directions(split, setup, fov, metric) for fov in fovs for metric in metrics]
    return files


def closedloop_directions(config: Mapping[str, Any]) -> list[tuple[str, float, str]]:
    """(setup, fov, metric) of every training-split direction set the closed loop captures ([] when disabled).

    ``closed_loop.setups`` × their FOVs (``closed_loop.fovs``, null = the
    acquisition's: ``acquisition.fovs`` for nearfield, ``acquisition.fixed_fov``
    for fixed_*) with ``closed_loop.metric``.
    """
    cl = config["closed_loop"]
    if not cl["enabled"]:
        return []
    acq = config["acquisition"]
    out = []
    for setup in cl["setups"]:
        fovs = setup_fovs(setup, acq["fovs"] if cl["fovs"] is None else cl["fovs"], acq["fixed_fov"])
        out += [(setup, float(f), cl["metric"]) for f in fovs]
    return out


def unseen_directions(acquisition: Mapping[str, Any]) -> list[str]:
    """Direction sets the unseen materials are looked up with: the training split's point and near-field sets of the error metric.

    ``[]`` when the config optimises neither (or not with the error metric).
    """
    if "error" not in acquisition["metrics"]:
        return []
    files = []
    if "point" in acquisition["setups"]:
        files.append(filenames.directions("train", "point", 0, "error"))
    if "nearfield" in acquisition["setups"]:
        files += [filenames.directions("train", "nearfield", fov, "error") for fov in acquisition["fovs"]]
    return files


def unseen_figures(*, unseen: bool, evaluated: bool) -> dict[str, list[str]]:
    """The unseen materials' figures: ``acquisition`` (next to the held-out errors) when they are evaluated, ``manifold`` (latent map) when there are any."""
    out: dict[str, list[str]] = {}
    if unseen and evaluated:
        out["acquisition"] = filenames.figure_files(filenames.UNSEEN_STEM)
    if unseen:
        out["manifold"] = filenames.figure_files(filenames.MANIFOLD_UNSEEN_STEM)
    return out


def unseen_map_q(manifold: Mapping[str, Any]) -> int:
    """The latent dimension of the map the unseen materials are drawn on: 2 when fitted, else the smallest."""
    dims = [int(q) for q in manifold["latent_dims"]]
    return 2 if 2 in dims else min(dims)


def check_closed_loop(config: Mapping[str, Any]) -> None:
    """The closed loop captures only direction sets the acquisition optimises; ConfigError naming the key."""
    cl = config["closed_loop"]
    if not cl["enabled"]:
        return
    acq = config["acquisition"]
    for setup in cl["setups"]:
        if setup not in acq["setups"]:
            raise ConfigError(f"config closed_loop.setups: {setup} is not in acquisition.setups {acq['setups']} "
                              "(or set closed_loop.enabled: false)")
    if cl["metric"] not in acq["metrics"]:
        raise ConfigError(f"config closed_loop.metric: {cl['metric']} is not in acquisition.metrics {acq['metrics']} "
                          "(or set closed_loop.enabled: false)")
    if cl["fovs"] is not None:
        extra = [f for f in cl["fovs"] if float(f) not in [float(a) for a in acq["fovs"]]]
        if extra:
            raise ConfigError(f"config closed_loop.fovs: {extra} not in acquisition.fovs {acq['fovs']}")
    big = [n for n in cl["n_images"] if int(n) > int(acq["n_max_images"])]
    if big:
        raise ConfigError(f"config closed_loop.n_images: {big} exceed acquisition.n_max_images = {acq['n_max_images']}")
    size = int(acq["grid"]) + (1 - int(acq["grid"]) % 2)  # the capture's image: brdfpipe.spec.nearfield.image_frame
    most = (MITSUBA_MAX_SAMPLES - 1) // (size * size)
    if int(cl["spp"]) > most:
        raise ConfigError(f"config closed_loop.spp = {cl['spp']}: at most {most} with acquisition.grid = {acq['grid']} "
                          f"(a capture renders its {size} × {size} pixels in one Mitsuba pass, at most 2^32 − 1 samples)")
    sensor = cl["sensor"]
    brackets = [float(b) for b in sensor["brackets"]]
    if min(brackets) != 1.0:
        scaled = ", ".join(f"{b / min(brackets):g}" for b in brackets)
        raise ConfigError(f"config closed_loop.sensor.brackets = {sensor['brackets']}: the shortest exposure must be 1 "
                          f"(the others are relative to it), e.g. [{scaled}]")
    if sensor["enabled"]:
        best = sensor_max_snr(sensor)
        if float(cl["min_snr"]) >= best:
            raise ConfigError(
                f"config closed_loop.min_snr = {cl['min_snr']}: no pixel can reach it, the sensor's best SNR is "
                f"{best:.4g} (√{len(brackets)} brackets × full_well / √(full_well + read_noise² + lsb²/12)); "
                "lower min_snr or raise closed_loop.sensor.full_well"
            )


def sensor_max_snr(sensor: Mapping[str, Any]) -> float:
    """The highest SNR any pixel of the closed loop's sensor can reach (``closed_loop.sensor``).

    The capture (:func:`brdfpipe.rendering.capture.expose`) estimates a
    pixel's SNR as Σe / √(Σe + k·read_noise² + k·lsb²/12) over its k
    unsaturated exposures, each below the full well: at most
    √k·full_well / √(full_well + read_noise² + lsb²/12), k = the number of
    brackets.  A ``min_snr`` at or above it masks every pixel.
    """
    fw = float(sensor["full_well"])
    rn = float(sensor["read_noise"])
    lsb = fw / ((1 << int(sensor["bits"])) - 1)
    k = len(sensor["brackets"])
    return math.sqrt(k) * fw / math.sqrt(fw + rn * rn + lsb * lsb / 12.0)


def curve_fov(acquisition: Mapping[str, Any]) -> float:
    """FOV of the error-vs-training-size curve (Xu Fig. 7): 25° when configured, else the first."""
    fovs = [float(f) for f in acquisition["fovs"]]
    return 25.0 if 25.0 in fovs else fovs[0]


def curve_directions(acquisition: Mapping[str, Any]) -> str | None:
    """The direction set of the training-size curve, or None when the config has none (no curve)."""
    if figure_specs.figure("xu-fig07").produced(acquisition):  # the curve is drawn exactly when it is computed
        return filenames.directions("train", "nearfield", curve_fov(acquisition), "error")
    return None


def albedo_map_dims(manifold: Mapping[str, Any]) -> list[int]:
    """Latent dimensions with an albedo map (a latent plane needs q ≥ 2)."""
    return [int(q) for q in manifold["latent_dims"] if int(q) >= 2]


def _track_figures(track: str, rule: str, settings: Mapping[str, Any]) -> dict[str, list[str]]:
    """The figures of ``track`` drawn by ``rule`` that a config with the track's ``settings`` produces: key → files."""
    return {f.key: filenames.figure_files(f.stem, table=f.table)
            for f in figure_specs.track_figures(track, rule) if f.produced(settings)}


def acquisition_figures(acquisition: Mapping[str, Any]) -> dict[str, list[str]]:
    """Xu 2016 figure analogues this config produces: key → files (PNG, PDF[, CSV, MD])."""
    return _track_figures("acquisition", "plot_acquisition_figures", acquisition)


def manifold_figures(manifold: Mapping[str, Any]) -> dict[str, list[str]]:
    """Soler 2018 figure analogues this config produces: key → files (PNG, PDF)."""
    return _track_figures("manifold", "plot_manifold_figures", manifold)


def render_figures(n_path_points: int) -> dict[str, list[str]]:
    """Rendering-track figures: the pre-render grid always; the path figures when there are path points."""
    return _track_figures("rendering", "plot_render_figures", {"n_path_points": n_path_points})


def floor_check_candidates(
    render: Mapping[str, Any], candidates: Mapping[str, tuple[str, float]], n_path_points: int
) -> list[str]:
    """Labels of the GPLVM candidates whose path points ``render.floor_check`` renders.

    None for ``floor_check.candidates: none`` or without path points; the
    default candidate (the first of ``candidates``, see
    :func:`manifold_candidates`) alone for ``default``; every candidate for
    ``all``.
    """
    check = render["floor_check"]
    if check["candidates"] == "none" or n_path_points == 0:
        return []
    labels = list(candidates)
    return labels[:1] if check["candidates"] == "default" else labels


# -- memory -------------------------------------------------------------------

#: Peak memory model of each rule's jobs, MB = base + per_material × N: a line
#: through the peak RSS (``max_rss`` of the benchmark files) of the default run
#: (N = 100, synthetic database, 2-core AMD EPYC) and of the tiny-point run
#: (N = 6); the local rules and ``interpolate_path_points`` were measured at
#: N = 100 with ``/usr/bin/time`` on the same run's inputs (one path point;
#: each further point adds :data:`PER_OUTPUT_MB`).  A slope 0 means the
#: two sizes peaked alike.  ``benches/bench_memory.py`` prints measured vs
#: declared for any finished run.  The declared value (:func:`mem_mb`) adds
#: :data:`MEMORY_HEADROOM` on top.
MEMORY_MB: dict[str, tuple[float, float]] = {
    # data stage
    "synthesize_material": (306.0, 0.0),
    "write_manifest": (135.0, 0.0),  # not measured at N = 100: as write_splits (the same imports)
    "ingest_material": (64.0, 0.0),
    "evaluate_fits": (480.0, 0.0),  # 287 MB measured at 2 threads (100 merl-nbrdf fits); ~90 MB more per material in flight, up to 4 threads
    "assemble_store": (78.0, 0.28),
    "write_splits": (135.0, 0.0),
    # acquisition track
    "map_logrelative": (170.0, 5.82),
    "accumulate_gram": (96.0, 2.93),
    "decompose_svd": (137.0, 5.32),
    "optimize_directions": (131.0, 13.4),
    "evaluate_directions": (280.0, 3.5),
    "check_directions": (136.0, 6.8),
    "evaluate_training_size": (250.0, 2.45),  # N = 100 only: slope as evaluate_directions'
    "plot_acquisition_figures": (157.0, 0.0),
    "capture_closedloop": (250.0, 0.0),  # 231-251 MB measured (default config, 33 × 33 images)
    "evaluate_closedloop": (900.0, 0.0),  # 1,135 MB measured: 10 held-out materials × 8 sets (default config)
    "plot_closedloop": (157.0, 0.0),  # as plot_acquisition_figures
    # materials outside the training database (config unseen); see SIZE_MEMORY_MB for their number
    "evaluate_unseen_fits": (480.0, 0.0),  # as evaluate_fits (same library call, up to 4 threads)
    "capture_unseen_closedloop": (250.0, 0.0),  # as capture_closedloop, plus every material's tables
    "evaluate_unseen": (280.0, 3.5),  # as evaluate_directions: one streamed pass per unseen database
    "locate_unseen": (276.0, 3.93),  # as compute_gram: one streamed pass over the store
    "plot_unseen_errors": (157.0, 0.0),  # as plot_acquisition_figures
    "plot_unseen_latent": (204.0, 0.0),  # as plot_manifold_figures
    # manifold track
    "compute_gram": (276.0, 3.93),
    "fit_gplvm": (95.0, 0.0),
    "measure_material_albedos": (720.0, 0.0),  # 8 float64 tables at a time: 709 MB peak RSS, N = 100
    "analyze_manifold": (380.0, 16.8),
    "measure_gplvm_candidate": (400.0, 16.8),
    "compare_spaces": (60.0, 0.0),
    "plot_manifold_figures": (204.0, 0.0),
    # rendering track
    "make_envmap": (116.0, 0.0),
    "prerender_materials": (350.0, 0.0),  # a batch: 248 MB for 1 material, 344 MB for 12 or 24 (4 tables cached)
    "interpolate_path_points": (250.0, 2.22),  # N = 100 only: grows with the rows read per block
    "render_path_points": (350.0, 0.0),  # as prerender_materials: several renders in one process
    "render_object_mask": (253.0, 0.0),  # as one render of render_path_points: one small render, not measured alone
    "bounce_shares": (110.0, 0.0),  # not measured: reads two images at a time, less than error_maps
    "error_maps": (110.0, 0.1),  # reads the I¹⁻ pre-renders too: twice error_maps' per-material share
    "interpolate_candidate_path_points": (250.0, 2.22),  # as interpolate_path_points
    "render_candidate_path_points": (350.0, 0.0),  # as render_path_points
    "measure_candidate_blends": (110.0, 0.1),  # as error_maps (smaller images)
    "summarize_floor_check": (120.0, 0.0),  # one small CSV per candidate
    "plot_floor_check": (240.0, 0.0),  # as plot_render_figures, without the images
    "plot_render_figures": (240.0, 1.0),
    # the report
    "write_claims": (60.0, 0.0),  # as compare_spaces (small CSVs); the library alone peaks at 24 MB (tiny run)
    "summarize_stage_times": (60.0, 0.0),  # as write_claims: one small TSV per job
    # the explorer: pre-renders in float32 and float64 (SVD), their half floats and base64 text
    "write_explorer": (250.0, 6.0),
}
#: MB per output on top of :data:`MEMORY_MB`, for rules whose jobs hold every
#: output in memory: ``interpolate_path_points`` holds one float64 MERL table
#: (35 MB) per path point, plus the blend of one column block.
PER_OUTPUT_MB: dict[str, float] = {"interpolate_path_points": 36.0, "interpolate_candidate_path_points": 36.0}
#: Declared / modelled peak on the first attempt (keeps declared within [1, 2] × measured).
MEMORY_HEADROOM: float = 1.3
#: Growth of the declared memory with each retry (attempt 2: × 1.5, attempt 3: × 2.25).
MEMORY_RETRY_GROWTH: float = 1.5


#: The most memory one job may declare (``mem_mb`` of its first attempt, :func:`mem_mb`): the per-job
#: memory of the Slurm profile (``profiles/slurm``: ``resources: mem_mb: 16000``), below the 24 GiB of
#: the build machine.  :func:`check_memory` refuses a configuration whose model exceeds it.
JOB_MEMORY_LIMIT_MB: int = 16000

#: The sizes at which :data:`MEMORY_MB` was measured (the default configuration): pixels of a render
#: (``render.resolution``) and of the environment map, a near-field image lattice (``acquisition.grid``²),
#: points of the albedo map (``manifold.albedo_grid``²), path points held at once, the largest latent
#: dimension + 4, the lattice pixels of one material's closed-loop images, held-out materials.
MEASURED_SIZES: dict[str, float] = {
    "render_pixels": 256 * 192,
    "envmap_pixels": 256 * 128,
    "lattice": 32 * 32,
    "albedo_points": 96 * 96,
    "path_chunk": 21,
    "q_plus": 5 + 4,
    "captured_lattice": (1 + 2) * 4 * 32 * 32,
    "test_materials": 10,
    "unseen_materials": 59,
}
#: Path points whose tables the manifold analyses hold at once (brdfpipe.manifold.analysis: 24, and the end).
PATH_CHUNK: int = 25

#: Memory that grows with a size beyond :data:`MEASURED_SIZES`, on top of :data:`MEMORY_MB`: per rule,
#: terms ``(size, multipliers, MB)`` adding ``MB × (size − measured size)⁺ × Π multipliers`` (a multiplier
#: is another size or ``materials``).  Measured with peak RSS on 2-core AMD EPYC (see each comment).
SIZE_MEMORY_MB: dict[str, tuple[tuple[str, tuple[str, ...], float], ...]] = {
    # the envmap: 302 B per pixel (sub-pixel sun coverage in float64); 4096 × 2048: 2,476 MB
    "make_envmap": (("envmap_pixels", (), 3.0e-4),),
    # a render: film, AOVs and float64 accumulators, 240 B per pixel (1024 × 768: 437 MB, 2048 × 1536:
    # 1,028 MB, 32 spp per pass); Mitsuba's copy of the envmap, 63 B per pixel (4096 × 2048: +529 MB)
    "prerender_materials": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    "render_path_points": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    "render_object_mask": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    "render_candidate_path_points": (("render_pixels", (), 2.4e-4), ("envmap_pixels", (), 6.5e-5)),
    # readers of the renders (tiny config, 12 materials, 32 × 24 → 384 × 288: +5.6, +30, +56 and +264 MB)
    "bounce_shares": (("render_pixels", (), 6.0e-5),),
    "error_maps": (("render_pixels", (), 2.8e-4), ("render_pixels", ("materials",), 2.0e-6)),
    "measure_candidate_blends": (("render_pixels", (), 2.8e-4), ("render_pixels", ("materials",), 2.0e-6)),
    "plot_render_figures": (("render_pixels", ("materials",), 4.3e-5),),
    "write_explorer": (("render_pixels", ("materials",), 2.0e-4),),
    # path points: an interpolated table (35 MB) and its perceptual features (53 MB) each, up to PATH_CHUNK at
    # once (tiny config, path_steps 4 → 30: +1,760 MB); the albedo map: distances and kernel values of every
    # point to every material, 8·(q + 4) bytes (albedo_grid 16 → 256 at q = 5, 12 materials: +78 MB)
    # the optimiser: transient per-configuration geometry, ~0.7 kB per lattice pixel (tiny model, 40
    # candidates: grid 12: 309 MB, 128: 334 MB, 256: 384 MB, 512: 492 MB; 200 candidates at 256: 401 MB)
    "optimize_directions": (("lattice", (), 7.0e-4),),
    # the capture: one configuration's footprint rays, 8.6 kB per lattice pixel (grid 32: 254 MB, 128: 274 MB,
    # 256: 717 MB, 512: 2,493 MB), and every image of the material kept (render, photograph, SNR, saturation
    # and geometry, 170 B per pixel); the evaluation holds every kept pixel's model column and value per source
    "capture_closedloop": (("lattice", (), 8.6e-3), ("captured_lattice", (), 1.7e-4)),
    "evaluate_closedloop": (("captured_lattice", ("test_materials",), 6.4e-5),),
    # the unseen materials: every observation table of a database in one job (~200 B per lattice pixel and
    # material); the streamed passes hold the unseen rows of a block (1.7 MB per material) and the cross products
    "capture_unseen_closedloop": (("captured_lattice", ("unseen_materials",), 2.0e-4),),
    "evaluate_unseen": (("unseen_materials", (), 2.0),),
    "locate_unseen": (("unseen_materials", (), 2.0),),
    "analyze_manifold": (("path_chunk", (), 88.0), ("albedo_points", ("materials", "q_plus"), 1.2e-5)),
    "measure_gplvm_candidate": (("path_chunk", (), 88.0), ("albedo_points", ("materials", "q_plus"), 1.2e-5)),
}

#: Config key of each size, for messages.
SIZE_KEYS: dict[str, str] = {
    "render_pixels": "render.resolution",
    "envmap_pixels": "render.envmap.width × height",
    "lattice": "acquisition.grid",
    "albedo_points": "manifold.albedo_grid",
    "path_chunk": "manifold.path_steps",
    "q_plus": "manifold.latent_dims",
    "captured_lattice": "acquisition.grid",
    "test_materials": "test_materials",
    "unseen_materials": "unseen.materials",
}

#: Rules whose jobs render or read the noise-floor check's scene (render.floor_check.resolution).
FLOOR_RULES: frozenset[str] = frozenset({
    "render_candidate_path_points", "measure_candidate_blends", "summarize_floor_check", "plot_floor_check",
    "interpolate_candidate_path_points",
})


def job_sizes(
    config: Mapping[str, Any], *, resolution: Sequence[int] | None = None, n_test: int = 10, n_unseen: int = 0
) -> dict[str, float]:
    """The sizes of :data:`MEASURED_SIZES` in ``config`` (``resolution``: the scene's, default ``render.resolution``).

    ``n_test``: the number of held-out materials; ``n_unseen``: of unseen materials (config ``unseen``).
    """
    acq, man, render = config["acquisition"], config["manifold"], config["render"]
    w, h = resolution if resolution is not None else render["resolution"]
    lattice = float(acq["grid"]) ** 2
    return {
        "render_pixels": float(w) * float(h),
        "envmap_pixels": float(render["envmap"]["width"]) * float(render["envmap"]["height"]),
        "lattice": lattice,
        "albedo_points": float(man["albedo_grid"]) ** 2,
        "path_chunk": float(min(int(man["path_steps"]) + 1, PATH_CHUNK)),
        "q_plus": float(max(int(q) for q in man["latent_dims"]) + 4),
        # lattice pixels of the closed loop's images of one material: Σ n_images over its direction sets
        "captured_lattice": float(sum(int(n) for n in config["closed_loop"]["n_images"])
                                  * max(1, len(closedloop_directions(config))) * lattice),
        "test_materials": float(n_test),
        "unseen_materials": float(n_unseen),
    }


def _size_terms(rule: str, n_materials: int, sizes: Mapping[str, float] | None) -> list[tuple[str, float, float]]:
    """(size, MB per unit of it above the measured size, that excess) of each size term of ``rule``."""
    if not sizes:
        return []
    have = {**sizes, "materials": float(n_materials)}
    out = []
    for size, multipliers, mb in SIZE_MEMORY_MB.get(rule, ()):
        per_unit = mb * math.prod(have[m] for m in multipliers)
        out.append((size, per_unit, max(0.0, have[size] - MEASURED_SIZES[size])))
    return out


def model_mb(rule: str, n_materials: int, *, outputs: int = 1, sizes: Mapping[str, float] | None = None) -> float:
    """Modelled peak memory (MB) of a job of ``rule``: :data:`MEMORY_MB`, :data:`PER_OUTPUT_MB`, :data:`SIZE_MEMORY_MB`.

    ``sizes``: :func:`job_sizes` of the job's configuration; None = the measured ones (no size term).
    """
    base, per = MEMORY_MB[rule]
    base += PER_OUTPUT_MB.get(rule, 0.0) * max(0, int(outputs) - 1)
    extra = sum(per_unit * excess for _, per_unit, excess in _size_terms(rule, n_materials, sizes))
    return base + per * int(n_materials) + extra


def mem_mb(
    rule: str, n_materials: int, attempt: int = 1, *, outputs: int = 1, sizes: Mapping[str, float] | None = None
) -> int:
    """``mem_mb`` a job of ``rule`` declares for ``n_materials`` materials at retry ``attempt`` (≥ 1).

    ``outputs``: how many outputs the job writes (counts only for the rules
    of :data:`PER_OUTPUT_MB`); ``sizes``: the config's :func:`job_sizes`
    (None: those :data:`MEMORY_MB` was measured at).  The model
    (:func:`model_mb`) × :data:`MEMORY_HEADROOM`, rounded up to 50 MB; at
    least 100 MB.  KeyError for a rule without a model.
    """
    need = model_mb(rule, n_materials, outputs=outputs, sizes=sizes)
    need *= MEMORY_HEADROOM * MEMORY_RETRY_GROWTH ** (max(1, int(attempt)) - 1)
    return max(100, int(math.ceil(need / 50.0)) * 50)


#: The rules of the materials outside the training database (config ``unseen``).
UNSEEN_RULES: tuple[str, ...] = ("evaluate_unseen_fits", "capture_unseen_closedloop", "evaluate_unseen",
                                 "locate_unseen", "plot_unseen_errors", "plot_unseen_latent")


def planned_rules(config: Mapping[str, Any], *, generated: bool, path_points: bool, floor_check: bool,
                  fits: bool = False, unseen: bool = False) -> list[str]:
    """The rules of :data:`MEMORY_MB` whose jobs ``config`` plans (for :func:`check_memory`).

    ``generated``: the run generates the synthetic database; ``fits``: it
    evaluates a database of fits (rule ``evaluate_fits`` instead of
    ``ingest_material``); ``unseen``: it has materials outside its database
    (config ``unseen``).
    """
    skip: set[str] = set()
    if not unseen:
        skip |= set(UNSEEN_RULES)
    else:
        if not closedloop_directions(config):
            skip.add("capture_unseen_closedloop")
        if not (closedloop_directions(config) or unseen_directions(config["acquisition"])):
            skip |= {"evaluate_unseen", "plot_unseen_errors"}
    if not generated:
        skip |= {"synthesize_material", "write_manifest"}
    skip.add("ingest_material" if fits else "evaluate_fits")
    if not closedloop_directions(config):
        skip |= {"capture_closedloop", "evaluate_closedloop", "plot_closedloop"}
    if not path_points:
        skip |= {"interpolate_path_points", "render_path_points", "error_maps"}
    if not floor_check:
        skip |= FLOOR_RULES
    if not curve_directions(config["acquisition"]):
        skip.add("evaluate_training_size")
    return [r for r in MEMORY_MB if r not in skip]


def _largest(rule: str, what: str, n_materials: int, n_out: int, sizes: Mapping[str, float], budget: float) -> float:
    """Largest value of ``what`` (a size, ``materials`` or ``outputs``) for which ``rule``'s model stays within ``budget``."""
    base, per = MEMORY_MB[rule]
    if what == "outputs":
        step = PER_OUTPUT_MB.get(rule, 0.0)
        rest = model_mb(rule, n_materials, outputs=1, sizes=sizes)
        return math.inf if step <= 0 else 1 + (budget - rest) / step
    if what == "materials":
        # the model is linear in N: base + per·N + N-proportional size terms
        at0, at1 = (model_mb(rule, n, outputs=n_out, sizes=sizes) for n in (0, 1))
        slope = at1 - at0
        return math.inf if slope <= 0 else (budget - at0) / slope
    terms = [t for t in _size_terms(rule, n_materials, sizes) if t[0] == what]
    per_unit = sum(t[1] for t in terms)
    if per_unit <= 0:
        return math.inf
    rest = model_mb(rule, n_materials, outputs=n_out, sizes=sizes) - sum(t[1] * t[2] for t in terms)
    return MEASURED_SIZES[what] + max(0.0, (budget - rest) / per_unit)


def check_memory(
    config: Mapping[str, Any],
    n_materials: int,
    rules: Sequence[str],
    *,
    outputs: Mapping[str, int] | None = None,
    floor_resolution: Sequence[int] | None = None,
    materials_key: str = "materials",
    n_test: int = 10,
    n_unseen: int = 0,
    limit_mb: int = JOB_MEMORY_LIMIT_MB,
) -> None:
    """Refuse a configuration one of whose jobs would declare more than ``limit_mb`` (:data:`JOB_MEMORY_LIMIT_MB`).

    For each rule (``rules``, :func:`planned_rules`) the first attempt's
    ``mem_mb`` (:func:`mem_mb`) with the config's sizes (the floor check's
    rules with ``floor_resolution``).  The job that needs most decides:
    :class:`ConfigError` naming the key whose term grew most (a size of
    :data:`SIZE_KEYS`, the number of path points, or the number of
    materials, ``materials_key``), the job's need, the limit, and the
    largest value of that key that every planned job fits with.
    """
    outputs = outputs or {}
    budget = limit_mb / MEMORY_HEADROOM  # what a model may reach (declared: × headroom, rounded up to 50 MB)
    jobs = []
    for rule in rules:
        if floor_resolution is None:
            scenes: list[Sequence[int] | None] = [None]
        elif rule in FLOOR_RULES:
            scenes = [floor_resolution]
        else:  # prerender_materials renders both scene folders
            scenes = [None, floor_resolution] if rule == "prerender_materials" else [None]
        for res in scenes:
            sizes = job_sizes(config, resolution=res, n_test=n_test, n_unseen=n_unseen)
            n_out = int(outputs.get(rule, 1))
            jobs.append((mem_mb(rule, n_materials, outputs=n_out, sizes=sizes), rule, res, sizes, n_out))
    need, rule, res, sizes, n_out = max(jobs, key=lambda j: j[0])
    if need <= limit_mb:
        return
    # what grew: the size term with the largest share, else path points, else materials
    grown = {size: per_unit * excess for size, per_unit, excess in _size_terms(rule, n_materials, sizes)}
    grown["outputs"] = PER_OUTPUT_MB.get(rule, 0.0) * (n_out - 1)
    grown["materials"] = MEMORY_MB[rule][1] * n_materials
    what = max(grown, key=lambda k: (grown[k], k != "materials"))
    most = min(_largest(r, what, n_materials, o, z, budget) for _, r, q, z, o in jobs
               if what != "render_pixels" or (q is None) == (res is None))
    why = f"one {rule} job would need {need:,} MB, above the {limit_mb:,} MB a job may have (the Slurm profile's per-job memory)"
    if what == "materials":
        raise ConfigError(f"config {materials_key}: {n_materials} materials: {why}; at most {int(most)} materials")
    if what == "outputs":
        raise ConfigError(f"config render.path_points × manifold.paths: {n_out} path points: {why}; "
                          f"at most {int(most)} path points")
    key = "render.floor_check.resolution" if what == "render_pixels" and res is not None else SIZE_KEYS[what]
    have = sizes[what]
    if what == "captured_lattice":
        per_grid2 = sizes[what] / sizes["lattice"]  # images per material
        if sizes["lattice"] > MEASURED_SIZES["lattice"]:
            key = "acquisition.grid"
            value, limit_text = f"{int(round(math.sqrt(sizes['lattice'])))}", f"at most {math.isqrt(int(most / per_grid2))}"
        else:
            key = "closed_loop.n_images × setups × fovs"
            value, limit_text = f"{int(per_grid2)} images per material", f"at most {int(most / sizes['lattice'])}"
    elif what in ("lattice", "albedo_points"):
        value, limit_text = f"{int(round(math.sqrt(have)))}", f"at most {math.isqrt(int(most))}"
    elif what in ("render_pixels", "envmap_pixels"):
        value, limit_text = f"{int(have):,} pixels", f"at most {int(most):,} pixels"
    else:
        value, limit_text = f"{int(have)}", f"at most {int(most)}"
    why = f"one {rule} job would need {need:,} MB with {n_materials} materials, above the {limit_mb:,} MB a job may have (the Slurm profile's per-job memory)"
    raise ConfigError(f"config {key} = {value}: {why}; {limit_text}")
