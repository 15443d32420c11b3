"""Benchmark runner, metrics and leaderboard files."""

from __future__ import annotations

import csv
import multiprocessing
import os
import shutil
import signal
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

from fricbench._validation import check_range
from fricbench.bench import runner
from fricbench.bench.error_budget import header_lines
from fricbench.bench.leaderboard import CSV_COLUMNS, compensator_category, write_leaderboards
from fricbench.bench.metrics import reversal_indices, score_run
from fricbench.bench.runner import (
    BenchConfigError,
    BenchTask,
    EpisodeRecord,
    plan_benchmark,
    read_compensator_config,
    run_benchmark,
    run_episode,
)
from fricbench.compensators import Compensator, compensator_registry, make_compensator
from fricbench.gym import get_spec


class _Exploding(Compensator):
    id: ClassVar[str] = "test-exploding"

    def _act(self, observation: np.ndarray) -> np.ndarray:
        if observation[1] > 0.05:  # x_ref beyond 5 mm: mid-episode
            raise RuntimeError("boom")
        return np.zeros(1)


class _NaN(Compensator):
    id: ClassVar[str] = "test-nan"

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return np.array([np.nan])


def test_reversal_indices_direct_and_after_dwell() -> None:
    v = np.array([0, 1, 2, 1, -1, -2, 0, 0, 0, 3, 0], dtype=float)
    assert list(reversal_indices(v, 1e-3)) == [4, 9]


def test_score_run_single_axis() -> None:
    t = np.arange(0, 1, 1e-3)
    x_ref = np.sin(2 * np.pi * t)
    x = x_ref - 1e-6 * np.sin(2 * np.pi * t)  # error peaks where the reference reverses
    m = score_run(t, x_ref, x, np.gradient(x_ref, t), np.zeros_like(t))
    assert m.max_error == pytest.approx(1e-6, rel=1e-3)
    assert m.rms_error == pytest.approx(1e-6 / np.sqrt(2), rel=1e-2)
    assert m.reversal_peak == pytest.approx(1e-6, rel=0.05)


def test_score_run_circle_deviation() -> None:
    t = np.arange(0, 2, 1e-3)
    th = np.pi * t
    r = 0.01
    x_ref = np.vstack([r * np.cos(th), r * np.sin(th)])
    x = np.vstack([(r + 2e-6) * np.cos(th), (r + 2e-6) * np.sin(th)])
    v = np.gradient(x_ref, t, axis=1)
    m = score_run(t, x_ref, x, v, np.zeros_like(x))
    assert m.max_error == pytest.approx(2e-6, rel=0.05)
    assert m.circular_deviation < 1e-7


def test_failing_and_nan_compensators_become_failed_rows() -> None:
    task = BenchTask("fricbench/PaperAxis-v0", "x", "s_curve", 0)
    rec = run_episode(_Exploding(), task)
    assert rec.status == "failed" and "boom" in rec.reason
    rec = run_episode(_NaN(), task)
    assert rec.status == "failed" and "non-finite" in rec.reason


def test_unknown_compensator_suggests() -> None:
    with pytest.raises(KeyError, match="did you mean 'kalman'"):
        make_compensator("kalmann")


def _rec(comp: str, seed: int, max_um: float) -> EpisodeRecord:
    return EpisodeRecord("fricbench/PaperAxis-v0", comp, "m_serial", seed, max_error=max_um * 1e-6,
                         rms_error=1e-6, reversal_peak=1e-6, effort_rms=1.0, effort_unit="N",
                         step_time=1e-5)


def test_leaderboard_rerun_replaces_own_rows_keeps_others(tmp_path) -> None:
    desc = {"fricbench/PaperAxis-v0": ("d", "fricbench/PaperAxis-v0")}
    write_leaderboards([_rec("none", 0, 20.0), _rec("kalman", 0, 8.0)], tmp_path, "cmd", "abc",
                       desc)
    write_leaderboards([_rec("kalman", 0, 5.0), _rec("kalman", 1, 6.0)], tmp_path, "cmd2",
                       "def", desc)
    with (tmp_path / "PaperAxis-v0.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    keyed = {(r["compensator"], r["seed"]): r for r in rows}
    assert set(keyed) == {("none", "0"), ("kalman", "0"), ("kalman", "1")}
    assert float(keyed[("kalman", "0")]["max_um"]) == pytest.approx(5.0)
    assert float(keyed[("kalman", "0")]["improvement_max_pct"]) == pytest.approx(75.0)
    for col in ("env", "compensator", "trajectory", "seed", "max_um", "rms_um",
                "reversal_peak_um", "improvement_max_pct"):
        assert col in rows[0]
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert "cmd2" in md and "def" in md and "Seeds" in md
    # both runs listed: `none` seed 0 is still the first one's row
    assert "  - `cmd` at commit `abc`: seeds [0], 1 row (`none`)" in md
    assert "  - `cmd2` at commit `def`: seeds [0, 1], 2 rows (`kalman`)" in md
    assert not list(tmp_path.glob(".*"))  # no temp files left behind


def test_a_fresh_write_drops_the_earlier_rows_of_the_envs_it_ran(tmp_path: Path) -> None:
    desc = {"fricbench/PaperAxis-v0": ("d", "fricbench/PaperAxis-v0")}
    failed = replace(_rec("kalman", 9, 1.0), status="failed", reason="boom")
    write_leaderboards([_rec("none", s, 20.0) for s in range(4)] + [failed], tmp_path, "old",
                       "abc", desc)
    assert (tmp_path / "PaperAxis-v0.failures.csv").exists()
    write_leaderboards([_rec("none", 0, 10.0), _rec("kalman", 0, 5.0)], tmp_path, "new", "def",
                       desc, fresh=True)
    rows = _rows(tmp_path / "PaperAxis-v0.csv")
    # the seeds 1-3 and the failure of the earlier run are gone: a table on fewer seeds
    assert sorted((r["compensator"], r["seed"], r["max_um"]) for r in rows) == [
        ("kalman", "0", "5.000"), ("none", "0", "10.000")]
    assert not (tmp_path / "PaperAxis-v0.failures.csv").exists()
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert "- Made by: `new`" in md and "old" not in md and "- Seeds: [0] (n = 1)" in md


PAPER = "fricbench/PaperAxis-v0"
DESC = {PAPER: ("d", PAPER)}


def test_the_settings_line_points_to_the_settings_file(tmp_path: Path) -> None:
    desc = {"fricbench/PaperAxis-v0": ("d", "fricbench/PaperAxis-v0")}
    tuned = replace(_rec("ilc", 0, 1.0), compensator_kwargs={"gain": 0.3})
    write_leaderboards([_rec("none", 0, 20.0), tuned], tmp_path,
                       "fricbench bench --compensator-config lb/bench.toml --seeds 0", "abc",
                       desc)
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert "why each differs from the default, a cut training budget included: the comments " \
           "of `lb/bench.toml`" in md
    assert '  - `ilc`: `{"gain": 0.3}`' in md


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def test_failed_rerun_keeps_the_good_row_and_records_the_failure(tmp_path: Path) -> None:
    failed = EpisodeRecord(PAPER, "kalman", "m_serial", 0, status="failed",
                           reason="RuntimeError: boom")
    write_leaderboards([_rec("none", 0, 20.0), _rec("kalman", 0, 8.0)], tmp_path, "c", "abc",
                       DESC)
    write_leaderboards([failed], tmp_path, "c", "def", DESC)
    rows = {r["compensator"]: r for r in _rows(tmp_path / "PaperAxis-v0.csv")}
    assert rows["kalman"]["status"] == "ok" and float(rows["kalman"]["max_um"]) == 8.0
    assert float(rows["kalman"]["improvement_max_pct"]) == pytest.approx(60.0)
    fails = _rows(tmp_path / "PaperAxis-v0.failures.csv")
    assert [(f["compensator"], f["seed"], f["commit"], f["reason"]) for f in fails] == [
        ("kalman", "0", "def", "RuntimeError: boom")]
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert "| `kalman` | m_serial | 0 | RuntimeError: boom | the earlier good row |" in md
    # a cell that never succeeded is a failed row; a later success clears the failure
    write_leaderboards([replace(failed, compensator="ilc")], tmp_path, "c", "def", DESC)
    assert {r["compensator"]: r["status"] for r in _rows(tmp_path / "PaperAxis-v0.csv")} == {
        "none": "ok", "kalman": "ok", "ilc": "failed"}
    write_leaderboards([_rec("kalman", 0, 7.0), _rec("ilc", 0, 1.0)], tmp_path, "c", "ghi",
                       DESC)
    assert not (tmp_path / "PaperAxis-v0.failures.csv").exists()
    assert "Failed runs" not in (tmp_path / "PaperAxis-v0.md").read_text()


def _write_seeds(out: str, seeds: list[int]) -> None:
    for s in seeds:  # one read-merge-write per row: many chances to interleave
        write_leaderboards([_rec("kalman", s, 5.0)], out, "c", "abc", DESC)


def test_concurrent_writers_lose_no_rows(tmp_path: Path) -> None:
    ctx = multiprocessing.get_context("fork")
    procs = [ctx.Process(target=_write_seeds, args=(str(tmp_path), list(range(i, 60, 2))))
             for i in range(2)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
    assert [p.exitcode for p in procs] == [0, 0]
    seeds = sorted(int(r["seed"]) for r in _rows(tmp_path / "PaperAxis-v0.csv"))
    assert seeds == list(range(60))
    assert len(_rows(tmp_path / "timings" / "PaperAxis-v0.csv")) == 60


def test_sigkill_mid_write_leaves_whole_tables_and_no_stale_lock(tmp_path: Path) -> None:
    proc = multiprocessing.get_context("fork").Process(
        target=_write_seeds, args=(str(tmp_path), list(range(10_000))))
    proc.start()
    table = tmp_path / "PaperAxis-v0.csv"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and (not table.exists() or len(_rows(table)) < 5):
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)  # most likely inside a read-merge-write
    proc.join()
    seeds = [int(r["seed"]) for r in _rows(table)]
    assert seeds == list(range(len(seeds))) and len(seeds) >= 5
    assert (tmp_path / "PaperAxis-v0.md").read_text().rstrip().endswith("m_serial.png)")
    # the killed writer's lock died with it: the next merge goes through
    write_leaderboards([_rec("none", 0, 20.0)], tmp_path, "c", "abc", DESC)
    assert len(_rows(table)) == len(seeds) + 1


def test_targets_only_for_what_ran(tmp_path: Path) -> None:
    recs = [replace(_rec(c, 0, um), trajectory=t) for t in ("m_serial", "curve")
            for c, um in (("none", 20.0), ("kalman", 8.0), ("friction-ff", 15.0))]
    write_leaderboards(recs, tmp_path, "c", "abc", DESC)
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert "- `kalman`: 60.0 % (target >= 50 %): met" in md
    assert "ilc" not in md and "rl-sac" not in md and "not run" not in md
    assert "best compensator" not in md  # a field-wide target needs the field
    full = [replace(r, compensator=c) for r in recs if r.compensator == "kalman"
            for c in ("ilc", "rl-sac")]
    write_leaderboards(full, tmp_path, "c", "abc", DESC)
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert "- best compensator `ilc`: 60.0 % (target >= 80 %): MISSED" in md
    assert "- `ilc`: 60.0 % (target >= 90 %): MISSED" in md


def test_timings_stay_out_of_the_tables(tmp_path: Path) -> None:
    recs = [_rec("none", 0, 20.0), _rec("kalman", 0, 8.0)]
    write_leaderboards(recs, tmp_path / "a", "c", "abc", DESC)
    write_leaderboards([replace(r, step_time=3.7e-5) for r in recs], tmp_path / "b", "c",
                       "abc", DESC)
    for name in ("PaperAxis-v0.csv", "PaperAxis-v0.md"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    assert "step_us" not in (tmp_path / "a" / "PaperAxis-v0.csv").read_text()
    assert "act time" not in (tmp_path / "a" / "PaperAxis-v0.md").read_text()
    assert {r["step_us"] for r in _rows(tmp_path / "b" / "timings" / "PaperAxis-v0.csv")} == {
        "37.00"}


def test_rewriting_a_committed_table_drops_only_its_timing_column(tmp_path: Path) -> None:
    """Same code, same rows: the tracked CSV and table come back minus ``step_us``/act time."""
    committed = Path(__file__).parents[2] / "leaderboards"
    shutil.copy(committed / "PaperAxis-v0.csv", tmp_path)
    shutil.copy(committed / "PaperAxis-v0.md", tmp_path)
    old_rows = _rows(tmp_path / "PaperAxis-v0.csv")
    old_md = (tmp_path / "PaperAxis-v0.md").read_text().splitlines()
    r = next(r for r in old_rows if (r["compensator"], r["seed"]) == ("none", "0"))
    # the run that wrote the row: its own columns, else (rows from before) the table's
    command = r.get("command") or next(
        ln for ln in old_md if ln.startswith("- Made by:")).split("`")[1]
    commit = r.get("commit") or next(
        ln for ln in old_md if ln.startswith("- Commit:")).split("`")[1]
    rec = EpisodeRecord(PAPER, "none", r["trajectory"], 0, max_error=float(r["max_um"]) * 1e-6,
                        rms_error=float(r["rms_um"]) * 1e-6,
                        reversal_peak=float(r["reversal_peak_um"]) * 1e-6,
                        effort_rms=float(r["effort_rms"]), effort_unit="N", step_time=1.0,
                        plant=r.get("plant") or "nominal")
    spec = get_spec(PAPER)
    write_leaderboards([rec], tmp_path, command, commit, {PAPER: (spec.description, PAPER)})
    # a column added since: empty, except the derived ones (the category declared now; rows
    # from before plants were drawn ran the nominal axis)
    derived = {"category": lambda row: compensator_category(row["compensator"]),
               "plant": lambda row: row.get("plant") or "nominal"}
    rewritten = (r["compensator"], r["trajectory"], r["seed"])
    run = {"command": command, "commit": commit}  # the rewritten row names the run that wrote it
    assert _rows(tmp_path / "PaperAxis-v0.csv") == [
        {c: derived[c](row) if c in derived else
         run[c] if c in run and (row["compensator"], row["trajectory"], row["seed"]) == rewritten
         else row.get(c, "") for c in CSV_COLUMNS}
        for row in old_rows]
    if "## Ranking" not in old_md or not any(ln.startswith("| compensator | category | n |")
                                             for ln in old_md):
        return  # committed before the statistics or the rows' n: awaits `make bench`
    act = next(ln for ln in old_md if ln.startswith("| compensator |")).split(" | ")
    drop = act.index("act time (us/step) |") if "act time (us/step) |" in act else None
    expected = []
    for ln in old_md:  # the table loses its last column, if it had the act-time one
        if drop is not None and ln.startswith("|"):
            ln = "|".join(ln.split("|")[:-2]) + "|"
        expected.append(ln)
    new_md = (tmp_path / "PaperAxis-v0.md").read_text().splitlines()
    # header lines added since the table was written (the error budget, the compensators'
    # notes; none for a table of today's format): computed, not rows
    trajs = sorted({r["trajectory"] for r in old_rows})
    comps = sorted({r["compensator"] for r in old_rows})
    added = {ln.rstrip("\n") for ln in header_lines(PAPER, trajs, comps)} - set(old_md)
    assert all(ln in new_md for ln in added)
    assert [ln for ln in new_md if ln not in added] == expected


def test_plan_checks_ids_and_seeds_naming_the_parameter() -> None:
    assert len(plan_benchmark([PAPER], ["none"], [0, 1], ["s_curve"])) == 2
    cases = [(["fricbench/PaperAxs-v0"], ["none"], [0], None, "env_ids", "did you mean"),
             ([PAPER], ["kalmn"], [0], None, "comp_ids", "did you mean 'kalman'"),
             ([PAPER], ["none"], [0], ["foo"], "trajectories", "expected one of"),
             ([PAPER], ["none"], [0], ["circle"], "trajectories", "2-axis"),
             ([PAPER], ["none"], [-3], None, "seeds", ">= 0"),
             ([PAPER], [], [0], None, "comp_ids", "at least one")]
    for envs, comps, seeds, trajs, param, match in cases:
        with pytest.raises(BenchConfigError, match=match) as info:
            plan_benchmark(envs, comps, seeds, trajs)
        assert info.value.parameter == param


def test_run_benchmark_checks_before_fitting(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_fit(*args: object) -> None:
        raise AssertionError("fitted before checking the arguments")

    monkeypatch.setattr(runner, "fit_compensators", no_fit)
    with pytest.raises(BenchConfigError, match="trajectories='foo'"):
        list(run_benchmark([PAPER], ["none"], [0], ["foo"], n_jobs=1, progress=False))


def test_run_benchmark_small_joblib() -> None:
    recs = list(run_benchmark(["fricbench/PaperAxis-v0"], ["none"], [0, 1], ["s_curve"],
                              n_jobs=2, progress=False))
    assert len(recs) == 2 and all(r.status == "ok" for r in recs)
    assert recs[0].max_error > 5e-6


@pytest.mark.slow
def test_run_benchmark_on_local_ray() -> None:
    ray = pytest.importorskip("ray")
    try:
        ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
        recs = list(run_benchmark(["fricbench/PaperAxis-v0"], ["none"], [0], ["s_curve"],
                                  backend="ray", progress=False))
        ref = list(run_benchmark(["fricbench/PaperAxis-v0"], ["none"], [0], ["s_curve"],
                                 n_jobs=1, progress=False))
    finally:
        ray.shutdown()
    assert recs[0].status == "ok"
    assert recs[0].max_error == pytest.approx(ref[0].max_error, rel=1e-12)


def test_every_registered_compensator_id_is_listed() -> None:
    for cid in ("none", "tf-precomp", "tf-lstm-precomp", "greybox-precomp", "friction-ff",
                "kalman", "ilc", "rl-sac", "rl-ppo"):
        assert cid in compensator_registry.ids()


class _Constant(Compensator):
    """Acts ``level`` every step: its effort shows which level it was built with."""

    id: ClassVar[str] = "test-constant"

    def __init__(self, *, level: float = 0.0, note: str = "") -> None:
        super().__init__()
        check_range("level", level, -1.0, 1.0)
        self.level = level
        self.note = note

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return np.full(1, self.level)


@pytest.fixture
def constant_compensator() -> Iterator[None]:
    compensator_registry.register(_Constant.id, _Constant)
    yield
    compensator_registry.unregister(_Constant.id)


@pytest.mark.parametrize(("comp_kwargs", "value", "message"), [
    ({"test-constnt": {"level": 0.1}}, "test-constnt", "unknown compensator id; did you mean "
                                                       "'test-constant'?"),
    ({"kalman": {"gain": 0.5}}, "kalman", "settings for a compensator that is not run"),
    ({"test-constant": {"levle": 0.1}}, "test-constant:levle",
     "not a keyword of compensator 'test-constant'; did you mean 'level'?; accepted: level, "
     "note"),
    ({"none": {"gain": 1.0}}, "none:gain", "it takes no keywords"),
    ({"rl-sac": {"algo": "ppo"}}, "rl-sac:algo", "the id 'rl-sac' names algo='sac'"),
    ({"test-constant": {"level": 2.0}}, "test-constant", "level=2.0: expected a value in [-1, 1]"),
    ({"test-constant": {"level": "high"}}, "test-constant", "level='high': expected a real "
                                                            "number"),
    ({"test-constant": 0.5}, "test-constant", "expected a mapping of keyword to value"),
])
def test_plan_checks_compensator_kwargs(constant_compensator: None, comp_kwargs: dict[str, Any],
                                        value: str, message: str) -> None:
    comps = ["none", "test-constant", "rl-sac"]
    with pytest.raises(BenchConfigError) as info:
        plan_benchmark([PAPER], comps, [0], ["s_curve"], comp_kwargs)
    assert (info.value.parameter, info.value.value) == ("comp_kwargs", value)
    assert message in info.value.problem, info.value.problem


def test_compensator_kwargs_reach_the_constructor_and_the_records(
        constant_compensator: None, tmp_path: Path) -> None:
    recs = list(run_benchmark([PAPER], ["none", "test-constant"], [0], ["s_curve"], n_jobs=1,
                              progress=False, comp_kwargs={"test-constant": {"level": 0.5}}))
    mine = next(r for r in recs if r.compensator == "test-constant")
    assert mine.status == "ok" and mine.compensator_kwargs == {"level": 0.5}
    assert mine.effort_rms == pytest.approx(0.5 * get_spec(PAPER).task.action_scale, rel=1e-3)
    assert next(r for r in recs if r.compensator == "none").compensator_kwargs == {}
    write_leaderboards(recs, tmp_path, "cmd", "abc", DESC)
    rows = {r["compensator"]: r for r in _rows(tmp_path / "PaperAxis-v0.csv")}
    assert rows["test-constant"]["compensator_kwargs"] == '{"level": 0.5}'
    assert rows["none"]["compensator_kwargs"] == ""
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert '  - `test-constant`: `{"level": 0.5}`\n' in md
    # a later run with the defaults replaces the row; the table says the settings are mixed
    write_leaderboards([replace(mine, seed=1, compensator_kwargs={})], tmp_path, "cmd", "abc",
                       DESC)
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert ('`test-constant`: `{"level": 0.5}`, the defaults (rows from runs with different '
            'settings)') in md


def test_no_settings_no_settings_line(tmp_path: Path) -> None:
    write_leaderboards([_rec("none", 0, 20.0)], tmp_path, "cmd", "abc", DESC)
    assert "Compensator settings" not in (tmp_path / "PaperAxis-v0.md").read_text()


@pytest.mark.parametrize(("content", "message"), [
    (None, "cannot read"),
    (b"[ilc\n", "invalid TOML"),
    (b"gain = 0.3\n", "gain = 0.3: expected a table of one compensator's settings"),
    (b"\xff\xfe", "not UTF-8"),
])
def test_compensator_config_file_problems(tmp_path: Path, content: bytes | None,
                                          message: str) -> None:
    path = tmp_path / "settings.toml"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(BenchConfigError, match=message) as info:
        read_compensator_config(path)
    assert (info.value.parameter, info.value.value) == ("comp_config", str(path))


def test_compensator_config_file(tmp_path: Path) -> None:
    path = tmp_path / "settings.toml"
    path.write_text('[ilc]\ngain = 0.3\nkeep = "last"\n["precomp:tf"]\nadvance = 2\n')
    assert read_compensator_config(path) == {"ilc": {"gain": 0.3, "keep": "last"},
                                             "precomp:tf": {"advance": 2}}


def test_a_circle_trace_is_the_scored_contour_error() -> None:
    """Issue 16 item 12: the leaderboard plot draws the quantity its legend's maximum is of."""
    from fricbench.bench.runner import BenchTask, run_episode
    from fricbench.compensators import make_compensator

    rec = run_episode(make_compensator("none"),
                      BenchTask("fricbench/CircleContouring-v0", "none", "circle", 0),
                      keep_trace=True, nominal=True)
    assert rec.status == "ok", rec.reason
    assert rec.trace_error is not None and rec.trace_error.ndim == 1
    peak = float(np.max(np.abs(rec.trace_error)))
    # subsampled: at most the full-rate maximum, and close to it
    assert 0.9 * rec.max_error <= peak <= rec.max_error * (1 + 1e-12)


def test_work_is_counted_per_env_fits_under_their_training_env() -> None:
    shifted = "fricbench/PaperAxisShifted-v0"
    assert get_spec(shifted).fit_on == PAPER
    work: dict[str, float] = {}
    records = list(run_benchmark([shifted], ["none", "tf-precomp"], [0], ["s_curve"], n_jobs=1,
                                 progress=False, work=work,
                                 comp_kwargs={"tf-precomp": {"n_runs": 1,
                                                             "run_duration": 4.0}}))
    assert [r.status for r in records] == ["ok", "ok"]
    # the fits ran on PaperAxis-v0's plant, the cells on the shifted env: each its CPU time
    assert set(work) == {PAPER, shifted} and all(v > 0 for v in work.values())


def test_the_bench_bar_counts_the_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    import tqdm

    bars: list[Any] = []

    class Recorder(tqdm.tqdm):  # type: ignore[misc]
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            kwargs["disable"] = True
            super().__init__(*args, **kwargs)
            self.counted = 0
            self.label = kwargs.get("desc")
            self.expected = kwargs.get("total")
            bars.append(self)

        def update(self, n: float | None = 1) -> bool | None:
            self.counted += int(n or 0)
            return super().update(n)

    monkeypatch.setattr(tqdm, "tqdm", Recorder)
    records = list(run_benchmark([PAPER], ["none", "ilc"], [0, 1], ["s_curve"], n_jobs=1))
    by_label = {b.label: b for b in bars}
    assert set(by_label) == {"fit", "bench"}
    # 2 compensators x 2 seeds: 4 fits, then 4 runs, each bar counting its own
    assert by_label["fit"].expected == by_label["fit"].counted == 4
    assert by_label["bench"].expected == by_label["bench"].counted == len(records) == 4
