"""The configuration's parse-time checks: everything a JSON schema cannot express.

Plain functions that the Snakefile (``workflow/rules/common.smk``) and the
tests call: one line for a schema violation naming the key
(:func:`schema_problem`), finite numbers, sizes that fit the data, latent
dimensions below the number of materials, the GPLVM candidates, the latent
paths, the closed loop's bounds.  A configuration that passes
:func:`check_config` builds a DAG whose every declared output some job
writes.  Every failure is a :class:`~brdfpipe.registry.errors.ConfigError`
naming the key.  Standard library only.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from brdfpipe.core import filenames
from brdfpipe.registry.errors import ConfigError
from brdfpipe.registry.manifold import STANDARD_FIT, GplvmCandidate, check_paths, data_space, default_paths

__all__ = [
    "ConfigError",
    "MITSUBA_MAX_SAMPLES",
    "config_key",
    "describe_schema_error",
    "schema_problem",
    "check_finite",
    "path_q",
    "manifold_candidates",
    "training_sizes",
    "check_config",
    "latent_paths",
    "check_closed_loop",
    "sensor_max_snr",
    "MAX_GRAM_BLOCKS",
    "check_gram_blocks",
]


#: Mitsuba renders at most 2^32 − 1 samples in one pass (its wavefront index is 32-bit; 3.9's own split of a
#: larger render fails).
MITSUBA_MAX_SAMPLES: int = 2**32


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


def manifold_candidates(manifold: Mapping[str, Any]) -> dict[str, GplvmCandidate]:
    """Label → :class:`~brdfpipe.registry.manifold.GplvmCandidate` of every GPLVM candidate: the default first.

    The default is (``space``, ``mu``) fitted with ``normalise``, ``method``
    and ``init``; each entry of ``candidates`` is fitted with its own
    ``normalise`` / ``method`` / ``init`` where it gives them, else with
    those.  :class:`ConfigError` naming ``manifold.candidates`` for two
    entries with the same label, and naming the key of a space whose blends
    cannot become tables (neither linear nor invertible: every candidate's
    blends are measured as tables).
    """
    fit = {k: manifold.get(k, d) for k, d in zip(("normalise", "method", "init"), STANDARD_FIT)}

    def candidate(c: Mapping[str, Any], key: str) -> GplvmCandidate:
        space = str(c["space"])
        if not data_space(space).blendable:
            raise ConfigError(f"config {key}: data space {space!r} is neither linear nor invertible, so its "
                              "blends cannot become tables; give its maps an inverse or choose another space")
        return GplvmCandidate(space, float(c["mu"]), bool(c.get("normalise", fit["normalise"])),
                              str(c.get("method", fit["method"])), str(c.get("init", fit["init"])))

    first = candidate(manifold, "manifold.space")
    out = {first.label: first}
    seen: set[str] = set()
    for k, c in enumerate(manifold.get("candidates") or []):
        cand = candidate(c, f"manifold.candidates[{k}].space")
        label = cand.label
        if label in seen:
            raise ConfigError(f"config manifold.candidates[{k}]: {label} is listed twice")
        seen.add(label)
        have = out.setdefault(label, cand)
        if have != cand:
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
    below the number of materials, a ``path_q`` without a model, a screening
    lattice not below the images', equal render seeds, and bad latent paths.
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
    acq = config["acquisition"]
    if 0 < int(acq["screen_grid"]) >= int(acq["grid"]):
        raise ConfigError(f"config acquisition.screen_grid = {acq['screen_grid']}: must be below acquisition.grid "
                          f"({acq['grid']}), or 0 to score every candidate at the full lattice")
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


def latent_paths(manifold: Mapping[str, Any], materials: Sequence[str]) -> list[tuple[str, str]]:
    """The configured latent paths (``manifold.paths``), else :func:`default_paths` (seeded)."""
    if manifold.get("paths"):
        return check_paths(manifold["paths"], materials)
    return default_paths(materials, int(manifold["seed"]))


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
    size = int(acq["grid"]) + (1 - int(acq["grid"]) % 2)  # the capture's image: brdfpipe.registry.nearfield.image_frame
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


#: At most this many column blocks of the streamed Gram matrix (``--set-scatter gram=N``): one per chunk of
#: the log-map (:data:`brdfpipe.data.logmap.CHUNK_COLS` = 36,450 columns) of the whole MERL grid (90 × 90 × 180
#: = 1,458,000 cells); more blocks would decode chunks twice (tests/test_plan.py checks the arithmetic).
MAX_GRAM_BLOCKS: int = 40


def check_gram_blocks(n_blocks: int) -> None:
    """The number of column blocks of the Gram matrix: 1 … :data:`MAX_GRAM_BLOCKS`; ConfigError naming the option."""
    if not 1 <= n_blocks <= MAX_GRAM_BLOCKS:
        raise ConfigError(
            f"--set-scatter gram={n_blocks}: must be between 1 and {MAX_GRAM_BLOCKS} (the Gram matrix is streamed "
            "in column blocks, at most one per log-map chunk of 36,450 of the 1,458,000 MERL cells)"
        )
