"""The acquisition set-ups and metrics: one record per set-up, which every stage asks.

A set-up (Xu et al. 2016) is how an acquisition observes a sample: point
samples (one light/view pair per observation), near-field images (camera
and light both move, §5.2), or images with one fixed camera or one fixed
light shared by all images (§8).  The geometry
(:mod:`brdfpipe.acquisition.geometry`), the optimiser
(:mod:`brdfpipe.acquisition.optimize`), the capture
(:mod:`brdfpipe.rendering.capture`), the figures and the planner read a
set-up's properties from its :class:`SetupKind` instead of testing names.

Adding a set-up: a record in :data:`SETUPS` here (its move set included),
its physics in ``acquisition/geometry.py`` where it has new physics (the
cells one configuration observes) and its name in the config schema's two enums (``acquisition.setups``, and
``closed_loop.setups`` for an image set-up; a test keeps them equal to this
registry).  See ``docs/design/extending.md``.

Adding a metric: a record in :data:`METRIC_KINDS` (its legend label and the
set-ups it applies to), its κ or error in ``acquisition/metrics.py`` and the
optimiser's choice of it in ``acquisition/optimize.py``, and its name in the
schema's ``acquisition.metrics`` enum (and ``closed_loop.metric`` for a
metric of image set-ups).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "SetupKind",
    "SETUPS",
    "SETUP_NAMES",
    "IMAGE_SETUPS",
    "FIXED_SETUPS",
    "MetricKind",
    "METRIC_KINDS",
    "METRICS",
    "IMAGE_METRICS",
    "setup_metrics",
    "DIRECTIONS_FORMAT",
    "setup",
    "setup_fovs",
    "PaperDirection",
    "PAPER_DIRECTIONS",
    "paper_direction",
]


@dataclass(frozen=True)
class SetupKind:
    """What the stages need to know about one acquisition set-up.

    ``images``: an observation is an image (it has a field of view and a
    pixel lattice; the closed loop can photograph it) rather than one
    direction pair.  ``fov``: which fields of view a config optimises it at:
    ``"none"`` (0, a point has none), ``"fovs"`` (every ``acquisition.fovs``)
    or ``"fixed"`` (``acquisition.fixed_fov``).  ``shared``: the direction the
    images of a set share (``"camera"``, ``"light"``) or ``""``; a shared
    direction's elevation is common to the set, and its optimiser searches
    two of the three axes per image.  ``axes``: the names of a
    configuration's three grid indices in logs.  ``wrap_phi``: the third axis
    is an azimuth that wraps round.  ``n_max_key``: the config key bounding
    the set size.  ``label``: a figure's legend; ``colour``: its curves'
    colour in the figures that compare set-ups (an index into
    :data:`brdfpipe.core.plot.COLOURS`).

    The optimiser's move set: ``moves``, the axes its local search moves each
    observation along (±step; a shared direction's elevation, axis 0, moves
    for the whole set instead); ``pinned``, (axis, grid index) pairs every
    configuration keeps, e.g. a ring of cameras at one elevation (a set-up
    with a shared direction only).  Candidates are drawn among the model's
    cells for a set-up without a shared direction (a configuration is a
    cell), else uniformly over the grid with the set's shared elevation and
    the pinned axes in place.
    """

    name: str
    label: str
    images: bool
    fov: str
    shared: str
    axes: tuple[str, str, str]
    wrap_phi: bool
    n_max_key: str
    moves: tuple[int, ...] = (0, 1, 2)
    pinned: tuple[tuple[int, int], ...] = ()
    colour: int = 5

    @property
    def unit(self) -> str:
        """What one observation is called in logs: ``image`` or ``direction``."""
        return "image" if self.images else "direction"


#: Every set-up, in the order the config's default lists them.
SETUPS: dict[str, SetupKind] = {
    s.name: s
    for s in (
        SetupKind("point", "point samples", images=False, fov="none", shared="",
                  axes=("iθh", "iθd", "iφd"), wrap_phi=True, n_max_key="n_max_point", colour=1),
        SetupKind("nearfield", "near-field", images=True, fov="fovs", shared="",
                  axes=("iθh", "iθd", "iφd"), wrap_phi=False, n_max_key="n_max_images", colour=2),
        SetupKind("fixed_camera", "fixed camera, moving light", images=True, fov="fixed", shared="camera",
                  axes=("θcam", "θlight", "φlight"), wrap_phi=True, n_max_key="n_max_images", moves=(1, 2),
                  colour=0),
        SetupKind("fixed_light", "fixed light, moving camera", images=True, fov="fixed", shared="light",
                  axes=("θlight", "θcam", "φcam"), wrap_phi=True, n_max_key="n_max_images", moves=(1, 2),
                  colour=4),
    )
}
#: The set-ups' names (the schema's ``acquisition.setups`` enum).
SETUP_NAMES: tuple[str, ...] = tuple(SETUPS)
#: The image set-ups (the schema's ``closed_loop.setups`` enum).
IMAGE_SETUPS: tuple[str, ...] = tuple(n for n, s in SETUPS.items() if s.images)
#: The set-ups whose images share one direction.
FIXED_SETUPS: tuple[str, ...] = tuple(n for n, s in SETUPS.items() if s.shared)


@dataclass(frozen=True)
class MetricKind:
    """One criterion of the direction optimiser.

    ``label``: how figures and claims name the direction sets it chooses.
    ``setups``: the set-ups it is optimised for (a configured metric is
    optimised for every configured set-up it applies to).
    """

    name: str
    label: str
    setups: tuple[str, ...]


#: The optimiser's criteria: the expected error E(S) (Xu eq. 15); the condition number κ over all k
#: components (Xu eq. 6 as printed); and Nielsen et al. 2015's κ as their released code computes it, of the
#: n × n matrix of the n chosen rows and the first n components — the "previous work" curve of Xu Figs. 6,
#: 18 and 19.  Nielsen's κ pairs n point samples with n components, so it is defined for point samples only
#: (an image set-up has more rows than components, where it is eq. 6's κ).
METRIC_KINDS: dict[str, MetricKind] = {
    m.name: m
    for m in (
        MetricKind("error", "min E(S) (eq. 15)", SETUP_NAMES),
        MetricKind("condition", "min κ, all k components (Xu eq. 6)", SETUP_NAMES),
        MetricKind("condition_nielsen", "min κ, first n components (Nielsen 2015 as released)", ("point",)),
    )
}
#: The metrics' names (the schema's ``acquisition.metrics`` enum).
METRICS: tuple[str, ...] = tuple(METRIC_KINDS)
#: The metrics of image set-ups (the schema's ``closed_loop.metric`` enum).
IMAGE_METRICS: tuple[str, ...] = tuple(
    m for m, kind in METRIC_KINDS.items() if any(SETUPS[s].images for s in kind.setups)
)
#: Format tag of a directions file (written by :func:`brdfpipe.acquisition.optimize.write_directions`, read by
#: the optimiser's reader and by the capture, :func:`brdfpipe.rendering.capture.read_configurations`).
DIRECTIONS_FORMAT: str = "brdfpipe.directions/1"


def setup(name: str) -> SetupKind:
    """The record of set-up ``name``; ValueError naming the known ones otherwise."""
    try:
        return SETUPS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown acquisition setup {name!r}; expected one of {', '.join(SETUPS)}") from None


def setup_fovs(name: str, fovs: list[float] | tuple[float, ...], fixed_fov: float) -> list[float]:
    """The fields of view a config optimises set-up ``name`` at (``acquisition.fovs``, ``fixed_fov``)."""
    where = setup(name).fov
    if where == "none":
        return [0]
    return list(fovs) if where == "fovs" else [fixed_fov]


def setup_metrics(name: str, metrics: list[str] | tuple[str, ...]) -> list[str]:
    """The configured ``metrics`` that set-up ``name`` is optimised with (in their order)."""
    setup(name)
    return [m for m in metrics if name in METRIC_KINDS[m].setups]


@dataclass(frozen=True)
class PaperDirection:
    """A near-field direction Xu et al. 2016 state in words (§6, Figs. 8, 9), read as a set of configurations.

    The sentence fixes the first image's half angle θh and its light's angle
    of incidence at the centre of the sample (θ of the light from the
    normal), nothing else.  ``theta_h_rule``: ``"nearest"`` — the θh cell of
    the MERL grid whose centre is nearest ``theta_h_deg``; ``"at_most"`` —
    every θh cell whose centre is at most ``theta_h_deg``.  The incidence lies
    within ``incidence_deg`` ± ``incidence_tol_deg``.  ``fov_deg``: the field
    of view the claim reads the sentence at; ``n_images``: the set size it is
    about (the images after the first are not stated: the optimiser adds
    them).  ``claim``: the key of the claim row that reports it.
    (:mod:`brdfpipe.acquisition.paper_directions` evaluates them.)
    """

    key: str
    claim: str
    fov_deg: float
    n_images: int
    theta_h_deg: float
    theta_h_rule: str
    incidence_deg: float
    incidence_tol_deg: float


#: "For one image, we capture a slightly offspecular direction (θh = 3°) at an angle of incidence of about 50°."
#: (no FOV stated: 25°, Fig. 9's, which draws it; "about 50°" as ± 5°) and "for two images, the first direction
#: for 15° field of view is an exact specular reflection at 60°" ("exact specular" as θh ≤ 0.5°, the first θh
#: cells; "at 60°" as ± 2.5°: MERL's θd cells are 1° wide) — Xu et al. 2016 §6.
PAPER_DIRECTIONS: tuple[PaperDirection, ...] = (
    PaperDirection("one-shot", "xu-one-shot-optimum", 25.0, 1, 3.0, "nearest", 50.0, 5.0),
    PaperDirection("two-shot", "xu-two-shot-first-specular", 15.0, 2, 0.5, "at_most", 60.0, 2.5),
)


def paper_direction(key: str) -> PaperDirection:
    """The record of :data:`PAPER_DIRECTIONS` named ``key``; ValueError naming the known ones otherwise."""
    for d in PAPER_DIRECTIONS:
        if d.key == key:
            return d
    raise ValueError(f"unknown paper direction {key!r}; expected one of {', '.join(d.key for d in PAPER_DIRECTIONS)}")
