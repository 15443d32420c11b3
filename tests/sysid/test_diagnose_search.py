"""The forward selection's held-out judgement (:mod:`fricbench.sysid.diagnose.search`)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from fricbench.sysid.diagnose.search import (
    _blocks,
    _effort_check_tolerance,
    _judged_ratio,
    block_left_out,
)
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS
from fricbench.sysid.diagnose.signals import block_folds


def heldout_ratio(cand: np.ndarray, base: np.ndarray) -> tuple[float, int | None]:
    """The ratio a candidate is judged on and the block left out."""
    ratio, left_out, note = _judged_ratio(float(cand.sum()), float(base.sum()), cand, base)
    assert (note == "") == (left_out is None)
    assert left_out == block_left_out(cand, base)
    return ratio, left_out


def _errors(rng: np.random.Generator, n: int = 20) -> np.ndarray:
    return rng.uniform(0.5, 2.0, n)


def test_the_ratio_is_that_of_the_sums_when_no_block_stands_alone() -> None:
    rng = np.random.default_rng(1)
    base = _errors(rng)
    cand = base * np.where(np.arange(20) % 2 == 0, 0.5, 1.5)  # wins half the blocks
    ratio, left_out = heldout_ratio(cand, base)
    assert left_out is None
    assert ratio == pytest.approx(cand.sum() / base.sum(), rel=1e-12)


def test_one_block_against_all_the_others_is_left_out() -> None:
    """A candidate 10 times better in 19 blocks and 100 times worse in one (a single event the
    fold fit never saw) is judged without that block; with it, it would be rejected."""
    rng = np.random.default_rng(2)
    base = _errors(rng)
    cand = 0.1 * base
    cand[7] = 100.0 * base[7]
    assert cand.sum() > base.sum()
    ratio, left_out = heldout_ratio(cand, base)
    assert left_out == 7
    keep = np.arange(20) != 7
    assert ratio == pytest.approx(cand[keep].sum() / base[keep].sum(), rel=1e-12)
    assert ratio < 0.11


def test_no_block_is_left_out_without_a_clear_majority() -> None:
    from scipy.stats import binom, norm

    rng = np.random.default_rng(3)
    base = _errors(rng)
    # one short of the majority a sign test at the detection rule's rate asks of 19 others
    level = 2.0 * norm.sf(DEFAULT_SETTINGS.detection_sd)
    n_wins = min(k for k in range(20) if binom.sf(k - 1, 19, 0.5) <= level) - 1
    assert n_wins == 13  # 14 of 19 by chance: 3.2 %; 13 of 19: 8.4 %
    cand = base.copy()
    cand[1:1 + n_wins] *= 0.1
    cand[1 + n_wins:] *= 1.05
    cand[0] = 100.0 * base[0]
    ratio, left_out = heldout_ratio(cand, base)
    assert left_out is None
    assert ratio == pytest.approx(cand.sum() / base.sum(), rel=1e-12)
    # one more win and the block goes
    cand[1 + n_wins] = 0.1 * base[1 + n_wins]
    assert heldout_ratio(cand, base)[1] == 0


def test_a_block_the_candidate_hardly_changes_is_not_left_out() -> None:
    """A block that holds most of the base's error (one rapid move) and that the candidate
    predicts about as badly: leaving it out would turn a 0.015 % loss into a 94 % cut."""
    base = np.full(20, 0.01)
    base[4] = 9.0
    cand = 0.06 * base
    cand[4] = 1.02 * base[4]
    assert cand.sum() / base.sum() > 0.99
    ratio, left_out = heldout_ratio(cand, base)
    assert left_out is None
    assert ratio == pytest.approx(cand.sum() / base.sum(), rel=1e-12)
    cand[4] = DEFAULT_SETTINGS.one_block_worse * base[4]
    assert heldout_ratio(cand, base)[1] == 4


@pytest.mark.parametrize("where", ["candidate", "base"])
def test_a_diverged_fold_keeps_the_plain_ratio(where: str) -> None:
    rng = np.random.default_rng(4)
    base = _errors(rng)
    cand = 0.1 * base
    (cand if where == "candidate" else base)[3] = np.inf
    ratio, left_out = heldout_ratio(cand, base)
    assert left_out is None
    assert ratio == (np.inf if where == "candidate" else 0.0)


def test_too_few_blocks_for_a_majority() -> None:
    base = np.array([1.0, 1.0, 1.0])
    cand = np.array([0.1, 0.1, 50.0])
    assert heldout_ratio(cand, base) == (pytest.approx(50.2 / 3.0), None)


@pytest.mark.parametrize(("n", "n_blocks"), [(1000, 20), (1003, 20), (230, 20)])
def test_blocks_are_fold_0s_then_fold_1s_and_cover_the_run(n: int, n_blocks: int) -> None:
    """The order the fold fits are judged in: the held-out blocks of fold 0, then fold 1."""
    folds = block_folds(n, n_blocks)
    blocks = _blocks(SimpleNamespace(folds=folds, n=n))  # type: ignore[arg-type]
    labels = [int(folds[a]) for a, _ in blocks]
    assert labels == sorted(labels)
    covered = np.zeros(n, dtype=int)
    for a, z in blocks:
        assert np.all(folds[a:z] == folds[a])
        covered[a:z] += 1
    assert np.all(covered == 1)


@pytest.mark.parametrize(("n_rows", "n_params"), [(80, 2), (80, 1), (160, 4), (2000, 2)])
def test_the_effort_checks_tolerance_covers_what_a_fit_on_few_rows_adds(n_rows: int,
                                                                        n_params: int) -> None:
    """Parameters fitted on one fold raise the other fold's error even when the extra force
    is zero: the tolerance of the position mode's effort check grows by that much on a short
    log and stays at ``settings.tolerance`` on a long one. Measured here by least squares
    on random regressors (a mass, damping, Coulomb level and ``n_params`` useless extras): the
    median inflation of the two-fold held-out error stays under the tolerance."""
    n_dec = n_rows + n_rows // 4
    sliding = np.ones(n_dec, dtype=bool)
    sliding[::5] = False  # rows at rest are not counted
    folds = block_folds(n_dec, 20)
    prep = SimpleNamespace(folds_dec=folds, sliding_dec=sliding)
    tol = _effort_check_tolerance(prep, n_params)  # type: ignore[arg-type]
    n_train = min(int(np.count_nonzero((folds != k) & sliding)) for k in (0, 1))
    assert tol == pytest.approx(DEFAULT_SETTINGS.tolerance + n_params / n_train)
    rng = np.random.default_rng(7)
    ratios = []
    for _ in range(400):
        base = rng.standard_normal((n_dec, 3))
        extra = rng.standard_normal((n_dec, n_params))
        u = base @ np.array([1.0, 0.5, 0.3]) + rng.standard_normal(n_dec)
        sse = []
        for cols in (base, np.hstack([base, extra])):
            total = 0.0
            for k in (0, 1):
                tr, te = (folds != k) & sliding, (folds == k) & sliding
                coef, *_ = np.linalg.lstsq(cols[tr], u[tr], rcond=None)
                total += float(np.sum((u[te] - cols[te] @ coef) ** 2))
            sse.append(total)
        ratios.append(sse[1] / sse[0])
    assert np.median(ratios) - 1.0 < tol
    if n_rows >= 2000:
        assert tol < DEFAULT_SETTINGS.tolerance + 0.003


def test_a_candidate_its_screen_gives_too_small_a_cut_is_listed_unfitted() -> None:
    """After the first step, a candidate ranked among the confirmed ones is fitted for real
    only when its linearised screen predicts the smallest cut any effect needs; the others
    stay in the step's candidates, with their screened ratio and why (the search's policy:
    a compliance screened at x0.996 took 4.5 s of a 25 s diagnosis and was rejected)."""
    import math

    from fricbench.bench.diagnose_timing import benchmark_run
    from fricbench.sysid.diagnose import diagnose

    result = diagnose(benchmark_run(4000, seed=0))
    steps = result.search.steps
    unfitted = [(i, c) for i, st in enumerate(steps) for c in st.candidates + st.rejected
                if c.note.startswith("not fitted: its screen")]
    assert unfitted
    for i, c in unfitted:
        assert i >= 2  # never at the first step, where every chosen candidate is fitted
        assert c.judged_on == "position (linearised)"
        need = DEFAULT_SETTINGS.min_gain + DEFAULT_SETTINGS.gain_per_param * c.n_params
        assert c.heldout_ratio >= math.exp(-need)


def test_an_effort_round_a_force_effect_wins_fits_no_output_effect(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """With the effort, force effects are taken first; the output effects (three fits each on
    the free-run position) are scored only in a round no force effect wins: here the last,
    once per output effect, and the rounds that added a force effect list the force effects
    only."""
    import fricbench.sysid.diagnose.search as SR
    from fricbench.bench.diagnose_timing import benchmark_run
    from fricbench.sysid.diagnose import diagnose
    from fricbench.sysid.diagnose.effects import get_effect

    scored: list[tuple[int, str]] = []
    original = SR._output_candidate

    def spy(model, name, *args, **kwargs):  # type: ignore[no-untyped-def]
        scored.append((len(model.effects), name))
        return original(model, name, *args, **kwargs)

    monkeypatch.setattr(SR, "_output_candidate", spy)
    report = diagnose(benchmark_run(4000, effort=True, seed=0)).to_dict()
    assert report["data"]["mode"] == "effort"
    steps = report["steps"]
    assert steps and all(get_effect(st["effect"]).kind == "force" for st in steps)
    for st in steps:
        assert all(get_effect(c["effect"]).kind == "force" for c in st["candidates"])
    last = {c["effect"] for c in report["rejected_at_last_step"]
            if get_effect(c["effect"]).kind == "output"}
    assert last and sorted(name for _, name in scored) == sorted(last)
    assert {n for n, _ in scored} == {len(steps)}
