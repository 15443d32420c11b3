"""Leaderboard statistics: bootstrap intervals, paired significance, rankings by category."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fricbench.bench.leaderboard import ranking, write_leaderboards
from fricbench.bench.runner import EpisodeRecord
from fricbench.bench.statistics import (
    MIN_SEEDS,
    cell_rng,
    median_ci,
    min_seeds,
    paired_difference,
    unpaired_difference,
)

PAPER = "fricbench/PaperAxis-v0"


def test_bootstrap_ci_is_reproducible_and_contains_the_median() -> None:
    x = np.random.default_rng(3).normal(10.0, 2.0, 10).tolist()
    a = median_ci(x, cell_rng(range(10), "kalman", "curve", "max_um"))
    b = median_ci(x, cell_rng(range(10), "kalman", "curve", "max_um"))
    assert a == b  # same seeds, same cell: the same interval, bit for bit
    assert a.low is not None and a.high is not None
    assert a.low <= a.median == float(np.median(x)) <= a.high
    assert a.low < a.high
    other = median_ci(x, cell_rng(range(10), "kalman", "s_curve", "max_um"))
    assert other.median == a.median  # another cell draws other resamples, same median


def test_degenerate_and_single_values_have_no_nan() -> None:
    same = median_ci([4.0] * 5, cell_rng([0], "c"))
    assert (same.median, same.low, same.high) == (4.0, 4.0, 4.0)
    one = median_ci([4.0, float("nan")], cell_rng([0], "c"))
    assert one.n == 1 and not one.has_ci and one.text() == "4.00 (n=1)"
    with pytest.raises(ValueError, match="finite"):
        median_ci([float("inf")], cell_rng([0], "c"))


def _rows(cuts: dict[str, list[float]], trajs: tuple[str, ...] = ("curve",)) -> list[dict[str,
                                                                                       str]]:
    rows = []
    for comp, per_seed in {"none": [0.0] * len(next(iter(cuts.values()))), **cuts}.items():
        for t in trajs:
            for s, v in enumerate(per_seed):
                rows.append({"compensator": comp, "trajectory": t, "seed": str(s),
                             "status": "ok", "improvement_max_pct": f"{v:.3f}"})
    return rows


def test_clear_difference_is_significant_and_a_tie_is_not() -> None:
    rng = np.random.default_rng(0)
    n = 10
    plant = rng.normal(0.0, 5.0, n)  # per-seed plant effect shared by every compensator
    clear_a = 80.0 + plant + rng.normal(0.0, 1.0, n)
    clear_b = 40.0 + plant + rng.normal(0.0, 1.0, n)
    tie_c = 20.0 + plant + rng.normal(0.0, 1.0, n)
    tie_d = 20.0 + plant + rng.normal(0.0, 1.0, n)
    rows = _rows({"a": list(clear_a), "b": list(clear_b), "c": list(tie_c), "d": list(tie_d)})
    ranked = ranking(rows, ["none", "a", "b", "c", "d"], ["curve"], list(range(n)))
    order = [r.compensator for r in ranked]
    assert order[:2] == ["a", "b"] and set(order[2:4]) == {"c", "d"} and order[4] == "none"
    diffs = {r.compensator: r.to_next for r in ranked}
    assert all(r.paired for r in ranked)
    assert diffs["a"] is not None and diffs["a"].excludes_zero()  # a above b
    first_of_tie = order[2]
    assert diffs[first_of_tie] is not None and not diffs[first_of_tie].excludes_zero()
    assert diffs["none"] is None  # the last has no next


def test_paired_beats_overlapping_intervals() -> None:
    """A small consistent gain on plants that spread widely: the intervals overlap, the
    paired difference is still significant (why the ranking pairs seeds)."""
    plant = np.linspace(0.0, 40.0, 10)
    a = {s: 50.0 + p + 1.0 for s, p in enumerate(plant)}
    b = {s: 50.0 + p for s, p in enumerate(plant)}
    ia = median_ci(list(a.values()), cell_rng(range(10), "a"))
    ib = median_ci(list(b.values()), cell_rng(range(10), "b"))
    assert ia.low is not None and ib.high is not None and ia.low < ib.high  # overlap
    d = paired_difference(a, b, cell_rng(range(10), "a-b"))
    assert d is not None and d.excludes_zero() and d.median == pytest.approx(1.0)


def _rec(comp: str, traj: str, seed: int, max_um: float) -> EpisodeRecord:
    return EpisodeRecord(PAPER, comp, traj, seed, max_error=max_um * 1e-6,
                         rms_error=max_um * 1e-7, reversal_peak=max_um * 1e-6, effort_rms=1.0,
                         effort_unit="N", step_time=1e-5)


def test_table_has_intervals_categories_rankings_and_no_nan(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    recs = []
    for s in range(10):
        base = 20.0 + rng.normal(0.0, 2.0)
        for t in ("curve", "m_serial"):
            recs += [_rec("none", t, s, base), _rec("kalman", t, s, 0.35 * base),
                     _rec("ilc", t, s, 0.05 * base), _rec("friction-ff", t, s, 0.6 * base)]
    write_leaderboards(recs, tmp_path / "a", "fricbench bench", "abc", {PAPER: ("d", PAPER)})
    write_leaderboards(recs, tmp_path / "b", "fricbench bench", "abc", {PAPER: ("d", PAPER)})
    md = (tmp_path / "a" / "PaperAxis-v0.md").read_text()
    assert md == (tmp_path / "b" / "PaperAxis-v0.md").read_text()  # reproducible bit for bit
    for needle in ("95% bootstrap", "| `kalman` | online |", "| `ilc` | trials |",
                   "| `friction-ff` | model |", "### Overall", "### Within `trials`",
                   "### Within `model`", "### Within `online`",
                   "Ranking: overall and within each category"):
        assert needle.lower() in md.lower(), needle
    assert "nan" not in md.lower() and "inf" not in md.replace("info", "").lower()
    csv_text = (tmp_path / "a" / "PaperAxis-v0.csv").read_text()
    assert csv_text.count("\n") == 1 + len(recs)  # the raw per-seed rows stay
    assert ",online,seed,fricbench bench,abc\n" in csv_text  # each row names its run
    assert ",trials,seed,fricbench bench,abc\n" in csv_text
    assert not any(math.isnan(float(x)) for x in csv_text.split(",") if _is_float(x))


def _is_float(x: str) -> bool:
    try:
        float(x)
    except ValueError:
        return False
    return True


def test_min_seeds_is_where_the_range_can_hold_the_median() -> None:
    # P(min <= median <= max) = 1 - 2^(1 - n): 0.9375 at 5 seeds, 0.969 at 6
    assert min_seeds(0.95) == MIN_SEEDS == 6
    assert min_seeds(0.5) == 2


def _board(tmp_path: Path, n_seeds: int, cut: dict[str, float]) -> str:
    """The markdown of ``n_seeds`` seeds where each compensator keeps ``1 - cut`` of none's
    max |e| (a seed-dependent wobble so that the intervals are not degenerate)."""
    recs = []
    for s in range(n_seeds):
        base = 20.0 + s
        recs.append(_rec("none", "curve", s, base))
        recs += [_rec(c, "curve", s, (1.0 - k + 0.01 * s) * base) for c, k in cut.items()]
    write_leaderboards(recs, tmp_path, "fricbench bench", "abc", {PAPER: ("d", PAPER)})
    return (tmp_path / "PaperAxis-v0.md").read_text()


def _overall(md: str) -> list[list[str]]:
    table = md.split("### Overall")[1].split("###")[0]
    return [[c.strip() for c in line.split("|")[1:-1]] for line in table.splitlines()
            if line.startswith("| ") and "rank" not in line]


def test_one_seed_ranks_by_the_point_value_and_says_there_is_no_interval(
        tmp_path: Path) -> None:
    md = _board(tmp_path, 1, {"kalman": 0.6, "ilc": 0.9, "friction-ff": -1.01})
    ranks = [(row[0], row[1]) for row in _overall(md)]
    assert ranks == [("1", "`ilc`"), ("2", "`kalman`"), ("3", "`none`"),
                     ("4", "`friction-ff`")]
    assert not any("n.s." in row[5] for row in _overall(md))
    assert "## Ranking (1 seed: no interval exists; ranked by the point value)" in md
    assert "## Max abs(e) (um): median (1 seed: no interval exists" in md
    assert "95 % CI" not in md


@pytest.mark.parametrize(("n_seeds", "held"), [(2, "50"), (5, "94")])
def test_few_seeds_carry_the_caveat_in_the_headings(tmp_path: Path, n_seeds: int,
                                                    held: str) -> None:
    md = _board(tmp_path, n_seeds, {"kalman": 0.6, "ilc": 0.9})
    caveat = (f"(only {n_seeds} seeds: a 95 % interval of a median needs at least 6; the range "
              f"of {n_seeds} holds the median {held} % of the time")
    assert f"## Max abs(e) (um): median [95 % CI] {caveat}" in md
    assert f"## Ranking {caveat}" in md


def test_enough_seeds_carry_no_caveat(tmp_path: Path) -> None:
    md = _board(tmp_path, MIN_SEEDS, {"kalman": 0.6})
    assert "## Max abs(e) (um): median [95 % CI]\n" in md and "## Ranking\n" in md


def test_unpaired_difference_of_disjoint_seeds() -> None:
    a = {0: 50.0, 1: 52.0, 2: 51.0, 3: 53.0}
    b = {4: 30.0, 5: 31.0, 6: 29.0, 7: 32.0}
    d = unpaired_difference(a, b, cell_rng(range(8), "a-b"))
    assert paired_difference(a, b, cell_rng(range(8), "a-b")) is None  # no common seed
    assert d is not None and d.median == pytest.approx(51.5 - 30.5) and d.excludes_zero()
    assert d == unpaired_difference(a, b, cell_rng(range(8), "a-b"))  # bit for bit
    close = unpaired_difference(a, {4: 50.5, 5: 52.5, 6: 51.0}, cell_rng(range(8), "a-c"))
    assert close is not None and close.n == 3 and not close.excludes_zero()
    one = unpaired_difference({0: 2.0}, b, cell_rng(range(8), "x"))
    assert one is not None and not one.has_ci and one.n == 1
    assert unpaired_difference({}, b, cell_rng(range(8), "x")) is None


def test_merged_table_gives_n_per_row_unpaired_comparisons_and_every_command(
        tmp_path: Path) -> None:
    """Two runs on other seeds merged into one table: `kalman` on seeds 0-3, `ilc` on 4-7,
    `none` on all eight."""
    rng = np.random.default_rng(2)
    base = 20.0 + rng.normal(0.0, 2.0, 8)
    run_a = [_rec(c, t, s, f * base[s]) for s in range(4) for t in ("curve", "m_serial")
             for c, f in (("none", 1.0), ("kalman", 0.4))]
    run_b = [_rec(c, t, s, f * base[s]) for s in range(4, 8) for t in ("curve", "m_serial")
             for c, f in (("none", 1.0), ("ilc", 0.05))]
    write_leaderboards(run_a, tmp_path, "fricbench bench --seeds 0 1 2 3", "aaa1111",
                       {PAPER: ("d", PAPER)})
    write_leaderboards(run_b, tmp_path, "fricbench bench --seeds 4 5 6 7", "bbb2222",
                       {PAPER: ("d", PAPER)})
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    # every contributing command, with its commit and the seeds of its rows
    assert "- Made by (rows merged from several runs" in md
    assert ("  - `fricbench bench --seeds 0 1 2 3` at commit `aaa1111`: seeds [0, 1, 2, 3], "
            "16 rows (`none`, `kalman`)") in md
    assert ("  - `fricbench bench --seeds 4 5 6 7` at commit `bbb2222`: seeds [4, 5, 6, 7], "
            "16 rows (`none`, `ilc`)") in md
    assert "- Seeds: [0, 1, 2, 3, 4, 5, 6, 7] (their union; the rows have different seeds" in md
    # n per row: none on 8 seeds, the others on 4
    assert "| `none` | online | 8 |" in md
    assert "| `kalman` | online | 4 |" in md and "| `ilc` | trials | 4 |" in md
    # ilc and kalman share no seed: compared unpaired, not left blank
    overall = md.split("### Overall")[1].split("###")[0]
    ilc_line = next(ln for ln in overall.splitlines() if "`ilc`" in ln)
    assert "(unpaired)" in ilc_line and ilc_line.rstrip().endswith("|")
    assert ilc_line.split("|")[-2].strip().startswith("+"), ilc_line
    kalman_line = next(ln for ln in overall.splitlines() if "`kalman`" in ln)
    assert "(unpaired)" not in kalman_line  # kalman against none: 4 common seeds, paired
    ranked = ranking([dict(r) for r in _csv_rows(tmp_path / "PaperAxis-v0.csv")],
                     ["none", "kalman", "ilc"], ["curve", "m_serial"], list(range(8)))
    assert [(r.compensator, r.paired, r.score.n) for r in ranked] == [
        ("ilc", False, 4), ("kalman", True, 4), ("none", True, 8)]
    assert ranked[0].to_next is not None and ranked[0].to_next.excludes_zero()
    # one run that wrote every row: the short form
    write_leaderboards(run_a, tmp_path / "one", "fricbench bench --seeds 0 1 2 3", "aaa1111",
                       {PAPER: ("d", PAPER)})
    one = (tmp_path / "one" / "PaperAxis-v0.md").read_text()
    assert "- Made by: `fricbench bench --seeds 0 1 2 3`\n- Commit: `aaa1111`\n" in one
    assert "- Seeds: [0, 1, 2, 3] (n = 4)\n" in one


def _csv_rows(path: Path) -> list[dict[str, str]]:
    import csv

    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))
