"""The ballbar reading of a circle in the runner and the leaderboard."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from fricbench.bench.leaderboard import CSV_COLUMNS, ballbar_plot_name, write_leaderboards
from fricbench.bench.runner import BenchTask, EpisodeRecord, run_episode
from fricbench.compensators import make_compensator

CIRCLE_ENV = "fricbench/CircleContouring-v0"


# --- the runner and the leaderboard ----------------------------------------------------------

@pytest.fixture(scope="module")
def circle_records() -> dict[bool, EpisodeRecord]:
    task = BenchTask(CIRCLE_ENV, "none", "circle", 0)
    return {keep: run_episode(make_compensator("none"), task, keep_trace=keep, nominal=True)
            for keep in (False, True)}


def test_the_runner_keeps_the_ballbar_reading_without_changing_a_score(
        circle_records: dict[bool, EpisodeRecord]) -> None:
    plain, traced = circle_records[False], circle_records[True]
    assert plain.status == traced.status == "ok", (plain.reason, traced.reason)
    assert plain.trace_ballbar is None
    run = traced.trace_ballbar
    assert run is not None and run.radius == pytest.approx(0.01)
    for name in ("max_error", "rms_error", "reversal_peak", "circular_deviation",
                 "reversal_spike", "effort_rms"):
        assert getattr(plain, name) == getattr(traced, name), name
    # full rate: one reading per sample; the ISO radial range the table scores is the range of
    # the reading while moving (the reference's own radius is R to rounding)
    assert run.deviation.size == traced.n_steps + 1
    m = run.moving
    assert np.ptp(run.deviation[m]) == pytest.approx(traced.circular_deviation, rel=1e-6)


def test_the_leaderboard_draws_and_links_the_ballbar_and_keeps_its_csv(
        tmp_path: Path, circle_records: dict[bool, EpisodeRecord]) -> None:
    desc = {CIRCLE_ENV: ("circle", CIRCLE_ENV)}
    plain = tmp_path / "plain"
    write_leaderboards([circle_records[False]], plain, "cmd", "abc", desc)
    traced = tmp_path / "traced"
    write_leaderboards([circle_records[True]], traced, "cmd", "abc", desc)
    png = traced / "plots" / ballbar_plot_name(CIRCLE_ENV, "circle")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (traced / "CircleContouring-v0.md").read_text()
    assert f"](plots/{png.name})" in md
    assert png.name not in (plain / "CircleContouring-v0.md").read_text()
    # the CSV is the same bytes with and without the trace, in the same columns
    csv_text = (traced / "CircleContouring-v0.csv").read_text()
    assert csv_text == (plain / "CircleContouring-v0.csv").read_text()
    with (traced / "CircleContouring-v0.csv").open() as fh:
        assert tuple(csv.DictReader(fh).fieldnames or ()) == CSV_COLUMNS
    # the tables above the plots are the same text
    head = md.split("## Error traces")[0]
    assert head == (plain / "CircleContouring-v0.md").read_text().split("## Error traces")[0]


def test_a_rerun_without_the_plotted_seed_keeps_the_ballbar_linked(
        tmp_path: Path, circle_records: dict[bool, EpisodeRecord]) -> None:
    desc = {CIRCLE_ENV: ("circle", CIRCLE_ENV)}
    write_leaderboards([circle_records[True]], tmp_path, "cmd", "abc", desc)
    png = tmp_path / "plots" / ballbar_plot_name(CIRCLE_ENV, "circle")
    before = png.read_bytes()
    write_leaderboards([circle_records[False]], tmp_path, "cmd", "def", desc)
    assert png.read_bytes() == before
    assert f"](plots/{png.name})" in (tmp_path / "CircleContouring-v0.md").read_text()
