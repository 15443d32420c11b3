"""The pictures of a simulated run: position and error, and the ballbar plot of a circle run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fricbench.axis import simulate
from fricbench.axis.export import (
    ballbar_figure,
    plot_ballbar,
    plot_run,
    radial_deviation,
    run_figure,
)
from fricbench.gym import get_spec
from fricbench.trajectories import make_trajectory

RADIUS = 0.005


@pytest.fixture(scope="module")
def circle_run():  # type: ignore[no-untyped-def]
    axis = get_spec("fricbench/CircleContouring-v0").axis
    ref = make_trajectory("circle", radius=RADIUS, feed=0.02, ts=axis.controller.ts)
    return simulate(axis, ref, seed=0)


def test_ballbar_png_is_written(circle_run, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "ballbar.png"
    k = plot_ballbar(circle_run, "circle", path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert path.stat().st_size > 10_000
    assert k > 1.0


def test_plotted_radial_error_is_the_computed_one(circle_run) -> None:  # type: ignore[no-untyped-def]
    # independently: the circle's centre is (-R, 0); the ballbar reads the true position
    x, y = circle_run.x_true[0] + RADIUS, circle_run.x_true[1]
    dr = np.hypot(x, y) - RADIUS
    theta_lib, dr_lib, sense = radial_deviation(circle_run)
    np.testing.assert_allclose(dr_lib, dr, rtol=0, atol=1e-15)
    assert set(np.unique(sense)) == {-1, 0, 1}  # "both": ccw, then cw, dwells at rest
    fig, k = ballbar_figure(circle_run, "circle")
    ax = fig.axes[0]
    lines = {ln.get_label().split(":")[0]: ln for ln in ax.get_lines()}
    for name, s in (("counter-clockwise", 1), ("clockwise", -1)):
        th, r_mm = (np.asarray(a) for a in lines[name].get_data())
        m = sense == s
        np.testing.assert_allclose(th, np.arctan2(y[m], x[m]), atol=1e-12)
        # plotted radius = R + k (r - R), in mm
        np.testing.assert_allclose((r_mm * 1e-3 - RADIUS) / k, dr[m], rtol=1e-9, atol=1e-12)
    # the magnification is stated on the plot, and the glitches are magnified into view
    assert any(f"magnified x{k:g}" in t.get_text() for t in fig.texts)
    assert 0.1 * RADIUS < k * np.abs(dr[sense != 0]).max() < 0.5 * RADIUS


def test_ballbar_refuses_a_single_axis_run() -> None:
    axis = get_spec("fricbench/PaperAxis-v0").axis
    res = simulate(axis, make_trajectory("s_curve", ts=axis.controller.ts), seed=0)
    with pytest.raises(ValueError, match="needs a 'circle' run"):
        radial_deviation(res)


def test_the_reference_is_drawn_over_the_measured_position(circle_run, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    fig = run_figure(circle_run, "circle")
    top, bottom = fig.axes
    lines = top.get_lines()
    refs = [ln for ln in lines if ln.get_color() == "k"]
    measured = [ln for ln in lines if ln not in refs]
    assert len(refs) == len(measured) == 2  # one of each per axis
    labels = [str(ln.get_label()) for ln in lines]
    assert "reference x_ref (dashed)" in labels
    assert "measured x, axis 0" in labels and "measured x, axis 1" in labels
    for ref in refs:
        assert ref.get_linestyle() != "-"  # dashed
        assert ref.get_zorder() > max(ln.get_zorder() for ln in measured)
        assert ref.get_linewidth() < min(ln.get_linewidth() for ln in measured)
    legend = top.get_legend()
    assert legend is not None and {t.get_text() for t in legend.get_texts()} >= {
        "reference x_ref (dashed)", "measured x, axis 0"}
    assert top.get_ylabel() == "position [mm]" and bottom.get_xlabel() == "time [s]"
    path = tmp_path / "run.png"
    plot_run(circle_run, "circle", path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
