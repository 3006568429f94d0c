"""The two papers' claims, each checked as its paper states it, against this run's own CSVs.

Every row quotes the paper's sentence (section, figure), says what is
compared with what — the paper's own comparison: Xu's images against the
previous work, Nielsen et al. 2015's κ as released — with the tolerance the
wording implies and why, gives this run's numbers and a verdict with its
cause (:mod:`.claims_base`: *reproduces*, *reproduces within the stated
tolerance*, *differs* with the measurement that shows why, *not checkable
here*).  Checks of this project's own that the papers do not make are rows
marked ``ours``, shown apart.  Nothing is typed in: each number is computed
from the run's CSVs; the database is read from them.

Its modules (one level of subpackages: siblings here): :mod:`.claims_base`
(the claim, its verdicts, the CSV readers), :mod:`.claims_xu` (accuracy per
number of samples: images, point sets, metrics), :mod:`.claims_setups`
(fields of view, training size, Fig. 8's directions, the fixed camera),
:mod:`.claims_soler` (the manifold and its renders), :mod:`.claims_ours`
(our own checks), :mod:`.claims_io` (``claims.{csv,json,rst}``, other runs
read back); this module re-exports what callers use.  :func:`compute_claims` makes every claim of a run, in report order.
"""

from __future__ import annotations

from pathlib import Path

from brdfpipe.report import claims_soler, claims_xu
from brdfpipe.report.claims_base import (
    CAUSES,
    CLAIM_COLUMNS,
    DIFFERS,
    NOT_CHECKABLE,
    OURS,
    REPRODUCES,
    SOLER,
    VERDICTS,
    WITHIN,
    XU,
    Claim,
    ClaimInputs,
    ClaimsInputError,
)
from brdfpipe.report.claims_io import (
    RunClaims,
    claims_table_rst,
    read_claims,
    read_run,
    rst_cell,
    verdict_counts,
    write_claims,
)
from brdfpipe.report.claims_ours import (
    UNSEEN_CLAIM_PREFIX,
    closed_loop_vs_table,
    is_unseen_claim,
    perceptual_monotone,
    spectralon_albedo,
    unseen_vs_heldout,
)
from brdfpipe.report.claims_soler import (
    NOISE_SIGMAS,
    albedo_in_unit_interval,
    blend_vs_noise_floor,
    eq7_bound,
    likelihood_converges,
    negligible_discontinuity,
    reproduction_vs_pca,
    second_bounce_share,
)
from brdfpipe.report.claims_xu import ErrorMeans, read_errors, xu_error_claims
from brdfpipe.report.claims_setups import one_shot_optimum, training_size_decreasing, two_shot_first_specular, \
    xu_setup_claims

__all__ = [
    "CAUSES",
    "CLAIM_COLUMNS",
    "VERDICTS",
    "REPRODUCES",
    "WITHIN",
    "DIFFERS",
    "NOT_CHECKABLE",
    "OURS",
    "XU",
    "SOLER",
    "NOISE_SIGMAS",
    "UNSEEN_CLAIM_PREFIX",
    "Claim",
    "ClaimInputs",
    "ClaimsInputError",
    "RunClaims",
    "compute_claims",
    "write_claims",
    "read_claims",
    "read_run",
    "read_errors",
    "verdict_counts",
    "claims_table_rst",
    "rst_cell",
    "is_unseen_claim",
]

def _xu(inputs: ClaimInputs) -> list[Claim]:
    # without errors.csv every claim from it says so: an empty table has none of their sets
    e = read_errors(inputs.errors) if inputs.errors is not None else ErrorMeans(Path("errors.csv"), "", {}, {})
    return (xu_error_claims(e) + xu_setup_claims(e)
            + [training_size_decreasing(inputs.training_size),
               one_shot_optimum(inputs.fig08_table, paper=inputs.paper_directions),
               two_shot_first_specular(inputs.fig08_table, paper=inputs.paper_directions)] + claims_xu.not_checkable_claims())


def _soler(inputs: ClaimInputs) -> list[Claim]:
    """Soler's claims but the likelihood's (which takes its database from the others)."""
    return [reproduction_vs_pca(inputs.reproduction), albedo_in_unit_interval(inputs.spaces),
            negligible_discontinuity(inputs.spaces), eq7_bound(inputs.paths),
            second_bounce_share(inputs.bounce_shares),
            blend_vs_noise_floor(inputs.errormap_summary, floor_check=False),
            blend_vs_noise_floor(inputs.floor_check, floor_check=True)] + claims_soler.not_checkable_claims()


def compute_claims(inputs: ClaimInputs) -> list[Claim]:
    """Every claim of both papers, then our own checks, in report order (one row per claim).

    A claim whose input this configuration does not produce is ``not
    checkable here``, saying so.  :class:`ClaimsInputError` when the CSVs
    name different databases.
    """
    out = _xu(inputs)
    soler = _soler(inputs)
    databases = {c.database for c in out + soler if c.database}
    soler.insert(4, likelihood_converges(inputs.traces, next(iter(databases)) if len(databases) == 1 else ""))
    out += soler
    out += [closed_loop_vs_table(inputs.closedloop), perceptual_monotone(inputs.paths)]
    databases = {c.database for c in out if c.database}
    if len(databases) > 1:
        by_db = {d: sorted({c.source for c in out if c.database == d}) for d in sorted(databases)}
        raise ClaimsInputError(f"the run's CSVs name different databases: {by_db}")
    if inputs.unseen is not None:  # materials outside the training database: each claim names its own database
        if inputs.errors is None:
            raise ClaimsInputError(f"{inputs.unseen}: the unseen materials' claims need errors.csv")
        out += unseen_vs_heldout(read_errors(inputs.errors), inputs.unseen)
    if inputs.unseen_albedo:
        out.append(spectralon_albedo(inputs.unseen_albedo))
    return out
