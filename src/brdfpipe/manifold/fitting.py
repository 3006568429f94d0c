"""Fitting the GPLVM: the start, the three optimisers of eq. 6, and the record of a fit (:class:`FitResult`).

:func:`fit` maximises the log-likelihood (:mod:`brdfpipe.manifold.likelihood`)
over the latent points, given the centred Gram matrix of the materials
(:mod:`brdfpipe.manifold.gram`).  Methods (:data:`METHODS`):

* ``newton`` (the default): exact-Hessian Newton steps from two start
  scales to a local maximum, the same on every BLAS kernel
  (:mod:`brdfpipe.manifold.newton`);
* ``hooke-jeeves``: the paper's direct search alone
  (:mod:`brdfpipe.manifold.hookejeeves`);
* ``hybrid`` (the default before issue 23): the initial scale is chosen by
  short Hooke–Jeeves trials (below), then scipy's L-BFGS-B on the analytic
  gradient (:func:`~brdfpipe.manifold.likelihood.log_likelihood_grad`) runs
  from that start to a stationary point, then the Hooke–Jeeves search
  continues from there (its finite steps can leave a stationary point that
  is not a maximum; every move it accepts is followed by a final L-BFGS
  polish).  Why not Hooke–Jeeves alone: measured on the default synthetic
  store (normalised, N = 100, one thread), the direct search stops 3–6 %
  below the L of a stationary point (q = 2: 9.24e8 vs 9.87e8; q = 5: 1.119e9
  vs 1.147e9) — moving one point at a time crawls along the narrow curved
  valleys of this ill-conditioned objective (L-BFGS needs 1,000–3,000
  iterations), and shrinking its steps only buys 0.5 % more in 10× the time;
  L-BFGS run after Hooke–Jeeves reaches a different, 0.1 % lower optimum
  than L-BFGS from the start.  The trace CSV records every stage.

The objective is multimodal and no optimiser here is global; ``hooke-jeeves``
and ``hybrid`` are not reproducible across BLAS kernels (``newton`` is:
:mod:`brdfpipe.manifold.newton`, "Reproducibility").

Initial scale
-------------
The initial points are the truncated PCA of the centred data (the top ``q``
eigenvectors of ``Gc`` times the square roots of their eigenvalues), then
scaled by one factor.  Since ``ℓ`` and the scale of ``X`` are interchangeable
(Soler §3), only the scale relative to ``ℓ`` matters, and the raw PCA
coordinates of BRDF data (units of sr⁻¹·√d) can be anything from 1e-2 to
1e4 × ℓ: far too small and ``K`` ≈ 11ᵀ + μI is nearly singular, far too large
and ``K`` ≈ (1 + μ)I carries no structure, and in both cases a local search
with fixed steps crawls (``init_scale="pca"`` keeps the scores as they are,
the paper's start).  Rules tried (:data:`INIT_SCALES`):

* ``"nn"``: median nearest-neighbour distance = ℓ;
* ``"rms"``: RMS pairwise distance = ℓ·√(2q) (unit variance per latent axis
  summed over q axes: the spread of a standard-normal prior, the usual GPLVM
  convention of unit-variance latents);
* ``"unit"``: the first PCA coordinate has unit standard deviation.

No rule wins everywhere (measured with N = 100 on the synthetic 100-material
store ``results/merl.zarr`` in the three spaces and on a random structured
Gram matrix, d = 4e6; final L after convergence, single-threaded):

========  =====  ===============  ===============  ===============
case      q      ``nn``           ``rms``          ``unit``
========  =====  ===============  ===============  ===============
raw       2      −2.54e16         **−1.69e16**     −1.80e16
raw       5      −2.49e16         **−6.57e15**     −7.10e15
cosine    2      **−4.49e9**      −1.50e10         −1.80e10
cosine    5      −4.81e9          −1.61e9          **−1.50e9**
log       2      **−5.01e7**      −1.08e8          −1.27e10
log       5      9.48e7           **1.46e8**       1.01e8
random    2      **1.91e8**       1.66e8           1.61e8
random    5      3.37e8           3.76e8           **4.05e8**
========  =====  ===============  ===============  ===============

so ``init_scale="best"`` (the default) runs every rule for ``trial_sweeps``
sweeps (10) and continues the search from the one with the highest L (that
is ``hybrid`` and ``hooke-jeeves``; ``newton`` runs from ``rms`` and ``unit``
to convergence and keeps the better: under L-BFGS to convergence, on the 18
default fits, ``nn`` never ended best — its final L was 0.43–0.97 of the
best rule's); on the
eight cases above it ends within 2 % of the best single rule or above it
(raw q = 2: −1.36e16), for about 30 % more time.  The tendencies: ``nn``
(points spread so neighbours sit at ℓ) wins at q = 2 when the data are on
the kernel's scale; when the data variance per column (tr Gc / (N·d)) is far
above the kernel's unit amplitude, as in raw units, the likelihood wants the
points much closer together than ℓ (strongly correlated K), which ``rms`` /
``unit`` give (factors 100× smaller than ``nn``'s on the raw store).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from brdfpipe.manifold import hookejeeves, newton
from brdfpipe.manifold.likelihood import (
    GramRoot,
    check_gram,
    check_hyper,
    check_q,
    log_likelihood,
    loglik_grad,
    sqdist,
)

__all__ = ["INIT_SCALES", "NEWTON_TRIAL_SCALES", "METHODS", "FitResult", "pca_init", "fit"]

logger = logging.getLogger("brdfpipe.manifold.fitting")

#: Initial-scale rules of :func:`fit` (plus ``"best"``: try all, keep the best L).
INIT_SCALES: Final = ("nn", "rms", "unit")
#: The rules ``init_scale="best"`` tries with ``method="newton"`` (module docstring, "Initial scale").
NEWTON_TRIAL_SCALES: Final = ("rms", "unit")
#: Optimisers of :func:`fit` (see the module docstring).
METHODS: Final = ("newton", "hybrid", "hooke-jeeves")


def pca_init(gram: ArrayLike, q: int) -> NDArray[np.float64]:
    """Truncated PCA scores of the centred data from its Gram matrix: ``V_q Λ_q^{1/2}`` (N × q), unscaled.

    Signs are fixed (largest-magnitude entry of each column positive) so the
    result is deterministic.
    """
    q = check_q(q)
    g = np.asarray(gram, dtype=np.float64)
    n = g.shape[0]
    if q > n:
        raise ValueError(f"latent dimension q = {q} exceeds the number of materials N = {n}")
    lam, V = np.linalg.eigh(0.5 * (g + g.T))
    top = np.argsort(lam)[::-1][:q]
    lam, V = np.clip(lam[top], 0.0, None), V[:, top]
    sign = np.sign(V[np.abs(V).argmax(axis=0), np.arange(q)])
    sign[sign == 0] = 1.0
    return V * sign * np.sqrt(lam)


def _scale_factor(Y: NDArray[np.float64], rule: str, ell: float) -> float:
    """Factor turning PCA scores ``Y`` into initial latents under ``rule`` (see module docstring)."""
    n, q = Y.shape
    if rule == "pca":  # the truncated PCA as it is (Soler §3)
        return 1.0
    if rule == "unit":
        sd = float(Y[:, 0].std())
        return 1.0 / sd if sd > 0 else 1.0
    D = np.sqrt(sqdist(Y))
    if rule == "nn":
        np.fill_diagonal(D, np.inf)
        nn = np.median(D.min(axis=1))
        return ell / nn if np.isfinite(nn) and nn > 0 else 1.0
    if rule == "rms":
        rms = float(np.sqrt((D**2).sum() / (n * (n - 1))))
        return ell * np.sqrt(2.0 * q) / rms if rms > 0 else 1.0
    raise ValueError(f"unknown init_scale {rule!r}; expected a number or one of best, pca, {', '.join(INIT_SCALES)}")


@dataclass
class FitResult:
    """Outcome of :func:`fit`."""

    X: NDArray[np.float64]
    log_likelihood: float
    #: ``(sweep, L)`` after each sweep; sweep 0 is the initial point.
    trace: list[tuple[int, float]]
    ell: float
    mu: float
    d: float
    init_scale: str
    init_factor: float
    initial_log_likelihood: float
    sweeps: int
    accepted_moves: int
    evaluations: int
    #: Largest |L_incremental − L_refactored| seen at a refactorisation (relative to |L|).
    max_drift: float
    seconds: float
    #: The best L reached from each initial-scale rule tried (``init_scale="best"``).
    scale_trials: dict[str, float] = field(default_factory=dict)
    #: ``"newton"``, ``"hybrid"`` or ``"hooke-jeeves"`` (:data:`METHODS`).
    method: str = "hooke-jeeves"
    #: Stage of each trace entry: ``start``, ``hooke-jeeves`` (a sweep), ``lbfgs`` (an iteration) or
    #: ``newton`` (a Newton step, or a step out of a saddle point).
    stages: list[str] = field(default_factory=list)
    #: L when the Hooke–Jeeves stage ended.
    hj_log_likelihood: float = float("nan")
    #: ``"hybrid"``: L-BFGS iterations of the polish (0 for the other methods).
    polish_iterations: int = 0
    #: ``"newton"``: Newton steps from the start scales that were not kept.
    trial_iterations: int = 0
    #: ``"newton"``: Newton steps (and steps out of saddle points) from the start that was kept.
    newton_iterations: int = 0
    #: ``"newton"``: evaluations of L alone (the trial points of the steps) and of L with its gradient and
    #: Hessian, every start included.
    gradient_evaluations: int = 0
    hessian_evaluations: int = 0



def _start_rule(Y: NDArray[np.float64], init_scale: str | float, ell: float) -> tuple[str, float]:
    """The label and factor of one start scale ``init_scale`` (a rule of :data:`INIT_SCALES` or a factor > 0)."""
    if isinstance(init_scale, str):
        return init_scale, _scale_factor(Y, init_scale, ell)
    factor = float(init_scale)
    if not np.isfinite(factor) or factor <= 0:
        raise ValueError(f"init_scale factor must be > 0, got {init_scale!r}")
    return "factor", factor


def _fit_newton(
    g: NDArray[np.float64], d: float, Y: NDArray[np.float64], *, ell: float, mu: float, init_scale: str | float,
    newton_iterations: int, gtol: float, max_escapes: int,
) -> FitResult:
    """:func:`fit` with ``method="newton"``: :func:`~brdfpipe.manifold.newton.newton_stages` from each start scale,
    the best L kept.

    ``init_scale="best"``: from each rule of :data:`NEWTON_TRIAL_SCALES`, to convergence; a later
    rule is kept only where its L exceeds the earlier one's by more than
    :data:`~brdfpipe.manifold.newton.GAIN_RESOLUTION`
    (a tie within rounding goes to the first rule, on every machine).
    """
    root = GramRoot(g)
    counts = newton.Counts()
    if isinstance(init_scale, str) and init_scale == "best":
        rules: list[tuple[str, float]] = [(r, _scale_factor(Y, r, ell)) for r in NEWTON_TRIAL_SCALES]
    else:
        rules = [_start_rule(Y, init_scale, ell)]
    runs = []
    for label, factor in rules:
        before = counts.newton_iterations
        X, L_start, hist = newton.newton_stages(Y * factor, root, d, ell, mu, newton_iterations=newton_iterations,
                                          gtol=gtol, max_escapes=max_escapes, counts=counts)
        L = log_likelihood(X, g, d, ell, mu)
        runs.append((L, label, factor, X, L_start, hist, counts.newton_iterations - before))
    best = runs[0]
    for run in runs[1:]:
        if run[0] > best[0] + newton.GAIN_RESOLUTION * abs(best[0]):
            best = run
    L_fin, label, factor, X_fin, L_init, hist, steps = best
    stages = ["start"] + [st for st, _ in hist]
    trace = list(enumerate([L_init] + [v for _, v in hist]))
    trace[-1] = (trace[-1][0], L_fin)
    res = FitResult(X_fin, L_fin, trace, ell, mu, d, label, factor, L_init, 0, 0, 0, 0.0, 0.0)
    res.scale_trials = {run[1]: run[0] for run in runs} if len(runs) > 1 else {}
    res.method, res.stages, res.hj_log_likelihood = "newton", stages, float("nan")
    res.newton_iterations = steps
    res.trial_iterations = counts.newton_iterations - steps
    res.gradient_evaluations = counts.evaluations
    res.hessian_evaluations = counts.hessians
    return res



@dataclass
class _HJStart:
    """Where :func:`fit`'s Hooke–Jeeves search starts: the scale rule and, after trials of every rule, their work."""

    label: str
    factor: float
    X: NDArray[np.float64]
    sweep0: int
    remaining: int
    #: L at the start (None: not computed yet).
    L_init: float | None
    #: The chosen trial's ``(sweep, L)`` trace (empty without trials).
    trace: list[tuple[int, float]] = field(default_factory=list)
    trials: dict[str, float] = field(default_factory=dict)
    accepted: int = 0
    evaluations: int = 0
    drift: float = 0.0


def _hj_start(
    s: hookejeeves.Settings, Y: NDArray[np.float64], init_scale: str | float, trial_sweeps: int, max_sweeps: int
) -> _HJStart:
    """The search's start: one rule, or (``init_scale="best"``) the best of :data:`INIT_SCALES` after trial sweeps."""
    if not (isinstance(init_scale, str) and init_scale == "best"):
        label, factor = _start_rule(Y, init_scale, s.ell)
        return _HJStart(label, factor, Y * factor, 0, int(max_sweeps), None)
    trials: dict[str, float] = {}
    acc = ev = 0
    drift = 0.0
    best: tuple[float, str, float, hookejeeves.State, list[tuple[int, float]]] | None = None
    n_trial = min(int(trial_sweeps), int(max_sweeps))
    for rule in INIT_SCALES:
        factor = _scale_factor(Y, rule, s.ell)
        st_t, tr_t, (a_t, e_t, dr_t) = hookejeeves.run(s, Y * factor, n_trial)
        acc, ev, drift = acc + a_t, ev + e_t, max(drift, dr_t)
        L_t = tr_t[-1][1]
        trials[rule] = L_t
        if best is None or L_t > best[0]:
            best = (L_t, rule, factor, st_t, tr_t)
    assert best is not None
    _, label, factor, st_b, trace = best
    sweep0 = trace[-1][0]
    return _HJStart(label, factor, st_b.X, sweep0, int(max_sweeps) - sweep0, trace[0][1], trace, trials, acc, ev,
                    drift)


@dataclass
class _HJEnd:
    """The outcome of :func:`fit`'s stages after the start (methods ``hybrid``, ``hooke-jeeves``)."""

    X: NDArray[np.float64]
    trace: list[tuple[int, float]]
    stages: list[str]
    L_init: float
    #: L when the Hooke–Jeeves stage ended.
    L_hj: float
    #: L-BFGS iterations.
    nit: int
    #: Accepted moves, evaluations and max drift of the search after the start.
    accepted: int
    evaluations: int
    drift: float


def _hooke_jeeves_stage(s: hookejeeves.Settings, start: _HJStart) -> _HJEnd:
    """Method ``hooke-jeeves``: the search continues from the start for the sweeps left."""
    st, tr2, (a2, e2, dr2) = hookejeeves.run(s, start.X, max(start.remaining, 0), start.sweep0)
    trace = start.trace + (tr2[1:] if start.trace else tr2)
    L_init = trace[0][1] if start.L_init is None else start.L_init
    stages = ["hooke-jeeves"] * len(trace)
    return _HJEnd(st.X, trace, stages, L_init, trace[-1][1], 0, a2, e2, dr2)


def _hybrid_stages(
    s: hookejeeves.Settings, start: _HJStart, Y: NDArray[np.float64], *, max_iter: int, ftol: float, gtol: float
) -> _HJEnd:
    """Method ``hybrid``: L-BFGS from the chosen start, Hooke–Jeeves from its optimum, L-BFGS again if that moved.

    (The search's finite steps can leave a stationary point.)
    """
    g, d_f, ell, mu = s.gram, s.d, s.ell, s.mu
    X_start = Y * start.factor
    L_init = log_likelihood(X_start, g, d_f, ell, mu)
    X1, hist1, nit = _lbfgs_polish(X_start, g, d_f, ell, mu, max_iter=max_iter, ftol=ftol, gtol=gtol)
    trace = [(0, L_init)] + [(k + 1, v) for k, v in enumerate(hist1)]
    stages = ["start"] + ["lbfgs"] * len(hist1)
    st, tr2, (a2, e2, dr2) = hookejeeves.run(s, X1, max(start.remaining, 0), len(trace) - 1)
    trace[-1] = (trace[-1][0], tr2[0][1])
    trace += tr2[1:]
    stages += ["hooke-jeeves"] * (len(tr2) - 1)
    X_fin, L_hj = st.X, trace[-1][1]
    if a2 > 0:
        X_fin, hist3, nit3 = _lbfgs_polish(st.X, g, d_f, ell, mu, max_iter=max_iter, ftol=ftol, gtol=gtol)
        last = trace[-1][0]
        trace += [(last + k + 1, v) for k, v in enumerate(hist3)]
        stages += ["lbfgs"] * len(hist3)
        nit += nit3
    trace[-1] = (trace[-1][0], log_likelihood(X_fin, g, d_f, ell, mu))
    return _HJEnd(X_fin, trace, stages, L_init, L_hj, nit, a2, e2, dr2)


def _hj_result(s: hookejeeves.Settings, start: _HJStart, end: _HJEnd, method: str) -> FitResult:
    """The :class:`FitResult` of a ``hybrid`` / ``hooke-jeeves`` fit (``seconds`` left at 0)."""
    res = FitResult(
        end.X, end.trace[-1][1], end.trace, s.ell, s.mu, s.d, start.label, start.factor, end.L_init,
        sum(st_ == "hooke-jeeves" for st_ in end.stages), start.accepted + end.accepted,
        start.evaluations + end.evaluations, max(start.drift, end.drift), 0.0,
    )
    res.scale_trials = start.trials
    res.method, res.stages, res.hj_log_likelihood, res.polish_iterations = method, end.stages, end.L_hj, end.nit
    return res


def _lbfgs_polish(
    X0: NDArray[np.float64], gram: NDArray[np.float64], d: float, ell: float, mu: float, *,
    max_iter: int, ftol: float, gtol: float,
) -> tuple[NDArray[np.float64], list[float], int]:
    """Quasi-Newton polish: scipy L-BFGS-B on −L/|L(X₀)| with :func:`~brdfpipe.manifold.likelihood.log_likelihood_grad`.

    Returns the final X, L after every iteration, and the iteration count.
    The objective is divided by a constant so that ``ftol`` / ``gtol`` are
    relative; a trial point where K is not positive definite scores +∞.
    """
    import scipy.optimize

    n, q = X0.shape
    scale = max(abs(log_likelihood(X0, gram, d, ell, mu)), 1.0)
    root = GramRoot(gram)

    last: dict[bytes, float] = {}

    def f(x: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        try:
            L, g = loglik_grad(x.reshape(n, q), root, d, ell, mu)
        except np.linalg.LinAlgError:
            return np.inf, np.zeros_like(x)
        last.clear()
        last[x.tobytes()] = L
        return -L / scale, -g.ravel() / scale

    def record(xk: NDArray[np.float64]) -> None:
        # the accepted iterate is normally the last point evaluated
        history.append(last[xk.tobytes()] if xk.tobytes() in last else log_likelihood(xk.reshape(n, q), gram, d, ell, mu))

    history: list[float] = []
    res = scipy.optimize.minimize(
        f, X0.ravel(), jac=True, method="L-BFGS-B", callback=record,
        options={"maxiter": int(max_iter), "maxfun": 4 * int(max_iter), "ftol": ftol, "gtol": gtol, "maxcor": 20},
    )
    X = res.x.reshape(n, q)
    if log_likelihood(X, gram, d, ell, mu) < log_likelihood(X0, gram, d, ell, mu):
        return X0.copy(), history, int(res.nit)  # never hand back a worse point
    return X, history, int(res.nit)



def _fit_hooke_jeeves(
    s: hookejeeves.Settings, Y: NDArray[np.float64], method: str, *, init_scale: str | float, trial_sweeps: int,
    max_sweeps: int, polish_iterations: int, polish_ftol: float, polish_gtol: float,
) -> FitResult:
    """:func:`fit` with ``method="hybrid"`` or ``"hooke-jeeves"``: the start, the stages, the result."""
    start = _hj_start(s, Y, init_scale, trial_sweeps, max_sweeps)
    if method == "hooke-jeeves":
        end = _hooke_jeeves_stage(s, start)
    else:
        end = _hybrid_stages(s, start, Y, max_iter=polish_iterations, ftol=polish_ftol, gtol=polish_gtol)
    return _hj_result(s, start, end, method)


def _check_fit_options(
    *, method: str, max_sweeps: int, refactor_every: int, step: float | None, min_step: float | None, ell: float,
    newton_iterations: int, max_escapes: int, newton_gtol: float,
) -> tuple[float, float]:
    """Check :func:`fit`'s options (ValueError naming the first bad one); returns the search's step and min_step."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}")
    if isinstance(max_sweeps, bool) or int(max_sweeps) < 0:
        raise ValueError(f"max_sweeps must be >= 0, got {max_sweeps!r}")
    if int(refactor_every) < 1:
        raise ValueError(f"refactor_every must be >= 1, got {refactor_every!r}")
    step0 = ell / 4.0 if step is None else float(step)
    min_step_f = ell * 1e-3 if min_step is None else float(min_step)
    if not step0 > 0 or not min_step_f > 0:
        raise ValueError("step and min_step must be > 0")
    for name, value, low in (("newton_iterations", newton_iterations, 0), ("max_escapes", max_escapes, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or int(value) < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    if not np.isfinite(float(newton_gtol)) or not float(newton_gtol) > 0:
        raise ValueError(f"newton_gtol must be a finite number > 0, got {newton_gtol!r}")
    return step0, min_step_f


def fit(
    gram: ArrayLike,
    d: float,
    *,
    q: int,
    ell: float = 1.0,
    mu: float = 1e-4,
    seed: int = 0,
    max_sweeps: int = 200,
    init_scale: str | float = "best",
    refactor_every: int = 200,
    step: float | None = None,
    min_step: float | None = None,
    trial_sweeps: int = 10,
    tol: float = 1e-15,
    ftol: float = 1e-9,
    method: str = "newton",
    polish_iterations: int = 5000,
    polish_ftol: float = 1e-12,
    polish_gtol: float = 1e-8,
    newton_iterations: int = 2000,
    newton_gtol: float = 1e-10,
    max_escapes: int = 10,
) -> FitResult:
    """Maximise eq. 6 over the latent points (``method``: see the module docstring).

    ``gram``: centred Gram matrix (N × N); ``d``: column count (enters only
    as a number).

    ``method="newton"`` (the default; :func:`brdfpipe.manifold.newton.newton_stages`): the start is
    :func:`pca_init` scaled by ``init_scale`` (``"best"``: from each rule of
    :data:`NEWTON_TRIAL_SCALES`, and the highest L is kept); from it, at most
    ``newton_iterations`` Newton (Levenberg–Marquardt) steps with the exact
    Hessian, until the largest gradient entry is ≤ ``newton_gtol``·|L| or no
    step can gain above the rounding level of L, leaving at most
    ``max_escapes`` saddle points.  The Hooke–Jeeves parameters
    (``max_sweeps``, ``seed``, …) are not used: the method has no random
    element, and its result is the same local maximum on every BLAS kernel
    (:mod:`brdfpipe.manifold.newton`, "Reproducibility").

    ``method="hybrid"`` / ``"hooke-jeeves"``: ``polish_*`` are L-BFGS-B's
    iteration cap and relative tolerances (hybrid only).  Initialisation: :func:`pca_init` scaled by ``init_scale``
    (a rule of :data:`INIT_SCALES`, a number = the factor itself, ``"pca"`` = the
    scores as they are (factor 1, Soler §3), or ``"best"``: every rule is run for ``trial_sweeps`` sweeps and the one with
    the highest L continues).  Search: a global step (default ``ℓ/4``) for
    every coordinate; each sweep visits the points in a seeded random order,
    tries ±step on each coordinate of the point (first improvement taken),
    then pattern moves along the point's displacement (doubling while L
    improves); a sweep without any accepted move halves the step; stop after
    ``max_sweeps`` sweeps or when the step falls below ``min_step`` (default
    ``ℓ·1e-3``).  Only strictly improving moves (ΔL > tol·|L|) are accepted, so
    the trace never decreases (up to the refactorisation drift, recorded in
    ``max_drift``).  ``K⁻¹`` and log|K| are updated by the rank-2 formulas
    and refactorised every ``refactor_every`` accepted moves and at the end.
    """
    q = check_q(q)
    ell, mu = check_hyper(ell, mu)
    g, d_f = check_gram(gram, d)
    step0, min_step_f = _check_fit_options(
        method=method, max_sweeps=max_sweeps, refactor_every=refactor_every, step=step, min_step=min_step, ell=ell,
        newton_iterations=newton_iterations, max_escapes=max_escapes, newton_gtol=newton_gtol,
    )
    t0 = time.perf_counter()
    Y = pca_init(g, q)
    if method == "newton":
        res = _fit_newton(
            g, d_f, Y, ell=ell, mu=mu, init_scale=init_scale, newton_iterations=int(newton_iterations),
            gtol=float(newton_gtol), max_escapes=int(max_escapes),
        )
        res.seconds = time.perf_counter() - t0
        logger.info(
            "GPLVM fit N=%d q=%d (newton): start %s x%.3g, L %.6g -> %.6g after %d Newton steps (%d from the other "
            "starts: %s), %d Hessians, %d evaluations of L, %.2f s",
            g.shape[0], q, res.init_scale, res.init_factor, res.initial_log_likelihood, res.log_likelihood,
            res.newton_iterations, res.trial_iterations,
            ", ".join(f"{k} {v:.6g}" for k, v in res.scale_trials.items()) or "none",
            res.hessian_evaluations, res.gradient_evaluations, res.seconds,
        )
        return res

    res = _fit_hooke_jeeves(
        hookejeeves.Settings(g, d_f, ell, mu, seed, step0, min_step_f, int(refactor_every), tol, ftol), Y, method,
        init_scale=init_scale, trial_sweeps=trial_sweeps, max_sweeps=max_sweeps,
        polish_iterations=polish_iterations, polish_ftol=polish_ftol, polish_gtol=polish_gtol,
    )
    res.seconds = time.perf_counter() - t0
    logger.info(
        "GPLVM fit N=%d q=%d (%s): L %.6g -> %.6g after %d Hooke-Jeeves sweeps (%d moves, %d evaluations, "
        "init %s x%.3g) -> %.6g after %d L-BFGS iterations, %.2f s",
        g.shape[0], q, method, res.initial_log_likelihood, res.hj_log_likelihood, res.sweeps, res.accepted_moves,
        res.evaluations, res.init_scale, res.init_factor, res.log_likelihood, res.polish_iterations, res.seconds,
    )
    return res

