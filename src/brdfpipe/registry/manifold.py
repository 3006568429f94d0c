"""The manifold's data spaces, GPLVM optimisers and Soler's latent paths: names and records.

A data space is how a material's table is mapped before the GPLVM sees it
(Soler §4.1–4.3 and this project's variants).  The maps themselves (NumPy)
live in :mod:`brdfpipe.manifold.spaces`, registered under the same names;
the planner, the schema (a test keeps its enums equal to
:data:`SPACE_NAMES`), the workflow's wildcards and the science modules read
the records here.

The latent paths: :data:`SOLER_PATHS` (Fig. 9), the path of Figs. 12/13
(:data:`SOLER_FIG12_PATH`, rendered beside the configured paths when the
database has both ends: :func:`rendered_paths`), their names in files
(:func:`path_name`), the seeded default (:func:`default_paths`) and the
check of a configured list (:func:`check_paths`, :class:`ConfigError` naming
the entry).  The measured materials of Fig. 1 (:data:`SOLER_FIG1_MATERIALS`).

Adding a data space: its :class:`DataSpace` record in :data:`DATA_SPACES`
here and its maps in ``manifold/spaces.py`` (and its name in the schema's
two enums, ``manifold.space`` and ``manifold.candidates[].space``).  See
``docs/design/extending.md``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final, NamedTuple

from brdfpipe.registry.errors import ConfigError

__all__ = [
    "DataSpace",
    "DATA_SPACES",
    "data_space",
    "SPACE_NAMES",
    "LINEAR_SPACES",
    "OPTIMISERS",
    "INITS",
    "STANDARD_FIT",
    "PAPER_RECIPE",
    "GplvmCandidate",
    "SOLER_PATHS",
    "SOLER_FIG12_PATH",
    "SOLER_FIG1_MATERIALS",
    "candidate_label",
    "is_paper_recipe",
    "describe_fit",
    "path_name",
    "default_paths",
    "check_paths",
    "rendered_paths",
]


@dataclass(frozen=True)
class DataSpace:
    """One data space of the manifold.

    ``linear``: the map scales each raw value by a constant (``z̃ = D z``), so
    the interpolant Σ wᵢ D zᵢ = D Σ wᵢ zᵢ blends the raw BRDFs, and images
    rendered from them, with the same weights (Soler §5.2).  A space that is
    not linear blends mapped values, which the interpolant maps back with the
    space's inverse: ``invertible`` says it has one (its maps in
    :mod:`brdfpipe.manifold.spaces` then carry it; a test keeps the two
    equal).  A space neither linear nor invertible cannot turn a blend into a
    table: the config check refuses it as ``manifold.space`` or a candidate's
    space (:attr:`blendable`).
    ``description``: one line for documentation and tables.
    """

    name: str
    linear: bool
    description: str
    invertible: bool = False

    @property
    def blendable(self) -> bool:
        """Whether a blend of this space's values can become a table: linear, or mapped back by its inverse."""
        return self.linear or self.invertible


#: Every data space, in the schema's order.
DATA_SPACES: dict[str, DataSpace] = {
    s.name: s
    for s in (
        DataSpace("raw", True, "the stored values (Soler et al. 2018)"),
        DataSpace("cosine", True, "each cell × cos θi · cos θo of its centre"),
        DataSpace("log", False, "ln((ρw + ε)/(ρ_ref w + ε)), the acquisition track's log-relative map (Xu eq. 1)",
                  invertible=True),
        DataSpace("relative", True, "each cell × cos θi · cos θo / max(ρ_ref, 1e-3)"),
        DataSpace("standardised", True, "each value × √(cos θi · cos θo) / σ, σ over the materials (floored)"),
    )
}


def data_space(name: str) -> DataSpace:
    """The record of data space ``name``: the one check of a space's name against :data:`DATA_SPACES`.

    ValueError ``unknown data space 'x'; expected one of …`` otherwise.
    """
    try:
        return DATA_SPACES[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown data space {name!r}; expected one of {', '.join(DATA_SPACES)}") from None


#: The data spaces' names (the schema's ``manifold.space`` enum).
SPACE_NAMES: tuple[str, ...] = tuple(DATA_SPACES)
#: The spaces whose interpolant is linear in the raw BRDFs.
LINEAR_SPACES: tuple[str, ...] = tuple(n for n, s in DATA_SPACES.items() if s.linear)
#: The GPLVM optimisers (``manifold.method``).
OPTIMISERS: tuple[str, ...] = ("newton", "hybrid", "hooke-jeeves")
#: The initialisations of a fit (``manifold.init``): the truncated PCA of the data scaled by the best of the
#: scale rules (``best``), by one rule (``rms``, ``unit``, ``nn``), or as it is (``pca``: the paper's, Soler §3).
INITS: tuple[str, ...] = ("best", "rms", "unit", "nn", "pca")


class GplvmCandidate(NamedTuple):
    """One GPLVM candidate: data space and μ, and how it is fitted (normalisation, optimiser, initialisation).

    ``normalise``: fit to G / (tr G / (N·d)) (a fixed signal variance equal to
    the data's) or to the Gram matrix as it is; ``method``: one of
    :data:`OPTIMISERS`; ``init``: one of :data:`INITS`.
    """

    space: str
    mu: float
    normalise: bool = True
    method: str = "newton"
    init: str = "best"

    @property
    def label(self) -> str:
        return candidate_label(self.space, self.mu, self.normalise, self.method, self.init)


#: How a candidate is fitted when its label names nothing but its space and μ: normalised Gram, the Newton
#: optimiser, the best-scaled PCA start (this project's fit since issue 23).
STANDARD_FIT: Final = (True, "newton", "best")
#: Soler et al. 2018's recipe (§3): raw BRDF values and Gram (no normalisation, no signal variance),
#: μ = 1e-4, Hooke–Jeeves direct search from the truncated PCA; ℓ = 1 is the workflow's ``manifold.ell``.
PAPER_RECIPE: Final = GplvmCandidate("raw", 1e-4, False, "hooke-jeeves", "pca")

#: The latent paths of Soler et al. 2018, Fig. 9 (used when all six materials exist).
SOLER_PATHS: tuple[tuple[str, str], ...] = (
    ("blue-metallic-paint", "dark-blue-paint"),
    ("teflon", "silver-paint"),
    ("black-oxidized-steel", "color-changing-paint3"),
)

#: The path of Soler et al. 2018, Figs. 12 and 13: MERL chrome to silver-paint, "in a 5D latent space";
#: Fig. 13 checks its midpoint.
SOLER_FIG12_PATH: tuple[str, str] = ("chrome", "silver-paint")

#: The four measured materials among Soler Fig. 1's fifteen renders, with their (row, column) there
#: (§4.3: "row 1, column 4 (two-layer silver); row 2, column 1 (chrome-steel); row 2, column 3
#: (gold-paint); and row 3, column 2 (brass)"; counted from 0 here).
SOLER_FIG1_MATERIALS: tuple[tuple[str, tuple[int, int]], ...] = (
    ("two-layer-silver", (0, 3)),
    ("chrome-steel", (1, 0)),
    ("gold-paint", (1, 2)),
    ("brass", (2, 1)),
)


def candidate_label(space: str, mu: float, normalise: bool = True, method: str = "newton", init: str = "best") -> str:
    """A GPLVM candidate's name in file names and tables: ``"<space>-mu<μ>"`` and what its fit does otherwise.

    ``raw-mu0.0001`` is fitted as :data:`STANDARD_FIT` (normalised Gram,
    ``newton``, ``best`` start); a fit that differs says how, in this order:
    ``-unnormalised``, ``-<method>``, ``-init-<init>``; e.g. the paper's recipe
    (:data:`PAPER_RECIPE`) is ``raw-mu0.0001-unnormalised-hooke-jeeves-init-pca``.
    ValueError for an unknown space, optimiser or initialisation, or a μ that
    is not a finite number ≥ 0.
    """
    data_space(space)
    mu_f = float(mu)
    if not math.isfinite(mu_f) or mu_f < 0:
        raise ValueError(f"mu must be a finite number >= 0, got {mu!r}")
    if method not in OPTIMISERS:
        raise ValueError(f"unknown optimiser {method!r}; expected one of {', '.join(OPTIMISERS)}")
    if init not in INITS:
        raise ValueError(f"unknown initialisation {init!r}; expected one of {', '.join(INITS)}")
    norm, std_method, std_init = STANDARD_FIT
    return (f"{space}-mu{mu_f:g}" + ("" if bool(normalise) == norm else "-unnormalised")
            + ("" if method == std_method else f"-{method}") + ("" if init == std_init else f"-init-{init}"))


def is_paper_recipe(space: str, mu: float, normalise: bool, method: str, init: str, ell: float = 1.0) -> bool:
    """Whether a fit is Soler et al. 2018's recipe (:data:`PAPER_RECIPE`, with ℓ = 1)."""
    p = PAPER_RECIPE
    return (space == p.space and math.isclose(float(mu), p.mu) and bool(normalise) == p.normalise
            and method == p.method and init == p.init and math.isclose(float(ell), 1.0))


def describe_fit(normalise: bool, method: str, init: str) -> str:
    """How a candidate is fitted, in words (for tables and claims)."""
    starts = {"best": "the PCA start scaled by the better of the rms / unit rules", "pca": "the truncated PCA as it is",
              "rms": "the PCA start scaled by the rms rule", "unit": "the PCA start scaled by the unit rule",
              "nn": "the PCA start scaled by the nearest-neighbour rule"}
    gram = ("normalised Gram (a fixed signal variance, tr G / (N·d))" if normalise
            else "raw Gram (no normalisation, no signal variance)")
    return f"{gram}, {method} from {starts.get(init, init)}"


def path_name(a: str, b: str) -> str:
    """File-name-safe name of the latent path from material ``a`` to ``b``: ``a--b``."""
    return f"{a}--{b}"


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
    names = [path_name(a, b) for a, b in out]
    for k, name in enumerate(names):
        j = names.index(name)
        if j < k:
            if out[j] == out[k]:
                raise ConfigError(f"{what}: listed more than once: {name}")
            raise ConfigError(f"{what}[{j}] {list(out[j])} and [{k}] {list(out[k])} share the file name {name}; "
                              "rename a material or drop one path")
    return out


def rendered_paths(paths: Sequence[tuple[str, str]], materials: Sequence[str]) -> list[tuple[str, str]]:
    """The latent paths the rendering track renders: ``paths`` (the configured ones), then Soler Figs. 12/13's.

    :data:`SOLER_FIG12_PATH` is added when the database has both its
    materials and ``paths`` does not already hold it (Figs. 12 and 13 show
    it); on other databases the paths are ``paths`` alone.
    """
    out = [tuple(p) for p in paths]
    known = set(materials)
    if all(m in known for m in SOLER_FIG12_PATH) and SOLER_FIG12_PATH not in out:
        out.append(SOLER_FIG12_PATH)
    return out  # type: ignore[return-value]
