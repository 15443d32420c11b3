"""The diagnosis' one criterion, its search and the uncertainty of what it selects.

The effective sample count against the closed forms of white and AR(1) noise, the covariance
against ordinary least squares' closed form, and the search on a scorer whose answer is known
(the settings and the guard against a new constant: ``test_diagnose_settings.py``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from fricbench.sysid.diagnose.criterion import (
    block_consistency,
    comparison_samples,
    criterion,
    criterion_change,
    described_sd,
    effective_samples,
    parameter_covariance,
    profile_statistic,
)
from fricbench.sysid.diagnose.selection import Scored, select
from fricbench.sysid.diagnose.settings import DiagnoseSettings


def test_white_noise_is_worth_its_samples() -> None:
    r = np.random.default_rng(0).standard_normal(20_000)
    assert effective_samples(r, 0.1) == pytest.approx(20_000, rel=0.1)


@pytest.mark.parametrize("phi", [0.5, 0.9])
def test_correlated_noise_is_worth_n_over_tau(phi: float) -> None:
    # AR(1): rho_k = phi^k, tau = (1 + phi) / (1 - phi)
    rng = np.random.default_rng(1)
    e = rng.standard_normal(40_000)
    r = np.empty_like(e)
    r[0] = e[0]
    for k in range(1, e.size):
        r[k] = phi * r[k - 1] + e[k]
    tau = (1 + phi) / (1 - phi)
    assert effective_samples(r, 0.1) == pytest.approx(r.size / tau, rel=0.15)


def test_a_drift_is_worth_few_samples() -> None:
    r = np.linspace(0.0, 1.0, 5000) + 1e-3 * np.random.default_rng(2).standard_normal(5000)
    assert effective_samples(r, 0.1) < 10


def test_two_structures_are_compared_on_the_richer_ones_samples() -> None:
    # the simpler model misses a drift (its residual worth a handful of samples); the richer
    # one leaves white noise: the comparison counts the richer one's samples, whichever of the
    # two is passed first, and the simpler one's when both have as many parameters
    rng = np.random.default_rng(3)
    noise = rng.standard_normal(5_000)
    drift = noise + 50.0 * np.linspace(0.0, 1.0, noise.size) ** 2
    rich = effective_samples(noise, 0.1)
    assert effective_samples(drift, 0.1) < 0.05 * rich
    assert comparison_samples(drift, noise, 2, 8, 0.1) == rich
    assert comparison_samples(noise, drift, 8, 2, 0.1) == rich
    assert comparison_samples(drift, noise, 4, 4, 0.1) == effective_samples(drift, 0.1)
    # a richer structure whose run diverged leaves no residual to count on
    diverged = noise.copy()
    diverged[10] = np.inf
    assert comparison_samples(drift, diverged, 2, 8, 0.1) == effective_samples(drift, 0.1)


def test_the_criterion_trades_error_against_parameters() -> None:
    # n_eff ln(SSE_new / SSE_old) + penalty dk
    assert criterion_change(0.5, 1.0, 3, 2, 10.0, 2.0) == pytest.approx(10 * math.log(0.5) + 2)
    assert criterion_change(0.95, 1.0, 3, 2, 10.0, 2.0) > 0.0  # 5 % is not worth a parameter
    assert criterion_change(0.95, 1.0, 3, 2, 1000.0, 2.0) < 0.0  # on many independent samples
    assert criterion_change(math.inf, 1.0, 3, 2, 10.0, 2.0) == math.inf
    assert criterion(1.0, 100, 10.0, 2, 2.0) == pytest.approx(10 * math.log(0.01) + 4)


def test_a_cut_consistent_over_the_blocks_passes_and_a_trade_does_not() -> None:
    """The block consistency (one-sided Wilcoxon signed-rank of the per-block cuts): an effect
    that cuts every block it acts on passes at the detection level whatever the untouched
    blocks do; one that cuts the few blocks where a misfit sits and worsens all the others
    does not, though its total cut is the same 30 %."""
    rng = np.random.default_rng(5)
    base = rng.uniform(1.0, 2.0, 20)
    base[:4] *= 10.0  # the misfit of the loop model sits in four blocks
    true = base.copy()
    true[::2] *= 1.0 - 0.3 * base.sum() / base[::2].sum()  # acts on half the blocks
    true[1::2] *= 1.0 + 1e-3 * rng.standard_normal(10)  # barely moves the others
    trade = base.copy()
    trade[:4] *= 0.1
    trade[4:] *= 1.0 + (0.9 * base[:4].sum() - 0.3 * base.sum()) / base[4:].sum()
    assert trade.sum() / base.sum() == pytest.approx(0.7)
    assert true.sum() / base.sum() == pytest.approx(0.7, abs=0.01)
    level = 0.0455  # 2 Phi(-2): the detection rule's false-detection rate
    p_true = block_consistency(true, base)
    p_trade = block_consistency(trade, base)
    assert p_true is not None and p_true < level
    assert p_trade is not None and p_trade > level
    # a block left out does not count, and fewer than 4 differing blocks give no test
    assert block_consistency(true, base, left_out=0) is not None
    assert block_consistency(base[:3] * 0.5, base[:3]) is None
    same = base.copy()
    same[:3] *= 0.5
    assert block_consistency(same, base) is None  # 17 blocks equal: 3 differ


def test_covariance_is_least_squares_closed_form_on_white_noise() -> None:
    rng = np.random.default_rng(3)
    X = rng.standard_normal((500, 3))
    y = X @ np.array([1.0, -2.0, 0.5]) + 0.1 * rng.standard_normal(500)
    theta, *_ = np.linalg.lstsq(X, y, rcond=None)
    r = y - X @ theta
    cov = parameter_covariance(X, r, n_eff=500.0)
    s2 = float(r @ r) / (500 - 3)
    assert np.allclose(cov, s2 * np.linalg.inv(X.T @ X), rtol=1e-8)
    # a correlated residual worth a tenth of its samples: ten times the variance
    assert np.allclose(parameter_covariance(X, r, n_eff=50.0), 10 * cov, rtol=1e-8)


@pytest.mark.parametrize("size", [0.0, 0.003, 0.01])
def test_the_profile_statistic_is_the_squared_wald_one_on_a_linear_model(size: float) -> None:
    # on a model linear in the size the two forms of the detection test are one:
    # SSE0 / SSE1 = 1 + z^2 / (n - p) exactly, z the size over its sd, so n ln(SSE0 / SSE1)
    # is z^2 to first order in z^2 / n, and both pass or fail the 2-sd level together
    rng = np.random.default_rng(5)
    n = 2000
    X = np.column_stack([np.ones(n), rng.standard_normal(n)])
    y = X @ np.array([0.3, size]) + 0.1 * rng.standard_normal(n)
    theta, *_ = np.linalg.lstsq(X, y, rcond=None)
    r1 = y - X @ theta
    r0 = y - np.mean(y)  # refitted without the size: the intercept alone
    z = theta[1] / math.sqrt(parameter_covariance(X, r1, n_eff=float(n))[1, 1])
    stat = profile_statistic(float(r1 @ r1), float(r0 @ r0), float(n))
    assert stat == pytest.approx(n * math.log1p(z * z / (n - 2)), rel=1e-9)
    assert stat == pytest.approx(z * z, rel=0.02, abs=1e-3)
    assert (stat > 4.0) == (abs(z) > 2.0)


def test_the_profile_statistic_is_zero_without_evidence() -> None:
    assert profile_statistic(0.0, 1.0, 10.0) == 0.0
    assert profile_statistic(1.0, math.inf, 10.0) == 0.0
    assert profile_statistic(1.0, math.nan, 10.0) == 0.0
    # a fit without the effect that does better (a poorer optimum) is no evidence for it
    assert profile_statistic(2.0, 1.0, 10.0) < 0.0


def test_an_undetermined_direction_gets_a_huge_finite_variance() -> None:
    X = np.column_stack([np.ones(100), np.ones(100)])  # the two columns are one
    cov = parameter_covariance(X, 0.1 * np.random.default_rng(4).standard_normal(100), 100.0)
    assert np.all(np.isfinite(cov))
    assert np.sqrt(cov[0, 0]) > 1e40


def test_described_sd_is_the_delta_method() -> None:
    # amplitude = hypot(a, b): var = g^T C g, g = (a, b) / amplitude
    row = np.array([3.0, 4.0])
    cov = np.diag([0.01, 0.04])
    sd = described_sd(lambda q: {"amp": float(math.hypot(q[0], q[1]))}, row, [0, 1], cov,
                      np.array([1e-7, 1e-7]))
    g = row / 5.0
    assert sd["amp"] == pytest.approx(math.sqrt(g @ cov @ g), rel=1e-5)


class _C:
    def __init__(self, name: str, requires: tuple[str, ...] = ()) -> None:
        self.name, self.requires = name, requires


def _scorer(cuts: dict[str, float], violations: dict[str, str] | None = None):  # type: ignore[no-untyped-def]
    """Held-out SSE = 1 times the cut of every candidate in, white residual of 1000 samples
    scaled to it (so n_eff is about 1000); 2 parameters each."""
    noise = np.random.default_rng(5).standard_normal(1000)

    def score(structure: tuple[str, ...], current: Scored | None = None) -> Scored:
        sse = 1000.0
        for name in structure:
            sse *= cuts.get(name, 1.0)
        bad = next((violations[n] for n in structure if violations and n in violations), None)
        return Scored(structure, sse, 1000, 2 * len(structure),
                      noise * math.sqrt(sse / 1000.0), bad)

    return score


def test_search_adds_what_pays_and_skips_constraints_and_prerequisites() -> None:
    score = _scorer({"big": 0.5, "tiny": 0.999, "ringing": 0.1, "child": 0.8},
                    {"ringing": "damping on its bound"})
    cands = [_C("tiny"), _C("child", ("big",)), _C("big"), _C("ringing")]
    sel = select(score((), None), cands, score, DiagnoseSettings())
    assert sel.best.structure == ("big", "child")
    rejected = {d["candidate"]: d["why"] for d in sel.decisions if not d["accepted"]}
    assert rejected["tiny"] == "does not lower the criterion"
    assert str(rejected["ringing"]).startswith("constraint: damping on its bound")


def test_backward_pass_drops_what_a_later_candidate_made_redundant() -> None:
    noise = np.random.default_rng(6).standard_normal(1000)

    def score(structure: tuple[str, ...], current: Scored | None = None) -> Scored:
        s = set(structure)
        # "b" alone fits badly from a cold start (0.4) but, started from the fit of {a, b},
        # as well as both together (0.1): once b is in, a adds nothing
        warm = current is not None and "b" in current.structure
        sse = 1000.0 * (0.1 if "b" in s and (warm or "a" in s) else 0.4 if "b" in s
                        else 0.3 if "a" in s else 1.0)
        return Scored(structure, sse, 1000, 2 * len(structure), noise * math.sqrt(sse / 1000))

    sel = select(score(()), [_C("a"), _C("b")], score, DiagnoseSettings())
    assert sel.best.structure == ("b",)
    back = [d for d in sel.decisions if d["pass"] == "backward"]
    assert [(d["candidate"], d["accepted"]) for d in back] == [("a", True), ("b", False)]
    # a candidate that another one requires is never removed
    sel = select(score(()), [_C("a"), _C("b", ("a",))], score, DiagnoseSettings())
    assert sel.best.structure == ("a", "b")


def test_a_term_whose_cut_shows_with_its_refinement_joins_with_it() -> None:
    # "parent" alone hardly cuts (its penalty outweighs it); with "child", which requires it,
    # the two cut half: a greedy search adding one at a time never gets there
    score = _scorer({"parent": 0.999, "child": 0.5})
    sel = select(score(()), [_C("parent"), _C("child", ("parent",))], score,
                 DiagnoseSettings())
    assert sel.best.structure == ("parent", "child")
    joined = [d for d in sel.decisions if d["accepted"]]
    assert [d["candidate"] for d in joined] == ["parent+child"]
    assert joined[0]["n_params"] == 4
    # a refinement that does not pay for itself does not ride on its parent's cut
    score = _scorer({"parent": 0.5, "child": 0.9995})
    sel = select(score(()), [_C("parent"), _C("child", ("parent",))], score,
                 DiagnoseSettings())
    assert sel.best.structure == ("parent",)
    # nor beyond the budget: a pair counts two
    score = _scorer({"parent": 0.999, "child": 0.5})
    sel = select(score(()), [_C("parent"), _C("child", ("parent",))], score,
                 DiagnoseSettings(max_effects=1))
    assert sel.best.structure == ()
