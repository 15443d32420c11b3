"""The ballbar reading of a circle and its polar picture."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fricbench.axis.ballbar import (
    CircleRun,
    ballbar_figure,
    ballbar_magnification,
    circle_run,
    plot_ballbar,
    radial_deviation,
)
from fricbench.trajectories import make_trajectory

R = 0.01


# --- radial_deviation: known geometry ---------------------------------------------------------

def test_a_concentric_circle_reads_its_radius_difference_at_its_own_angle() -> None:
    phi = np.linspace(-np.pi + 0.01, np.pi, 500)
    c, d = (0.3, -0.2), 4e-6
    theta, dr = radial_deviation(c[0] + (R + d) * np.cos(phi), c[1] + (R + d) * np.sin(phi),
                                 c, R)
    np.testing.assert_allclose(dr, d, rtol=0, atol=1e-15)
    np.testing.assert_allclose(theta, phi, rtol=0, atol=1e-12)


def test_an_offset_circle_reads_plus_minus_its_offset_and_a_cosine() -> None:
    # circle of radius R centred e off the pivot along +X: r - R = +e at 0 deg, -e at 180 deg
    # (collinear, exact), and e cos(theta) to first order in e / R
    e = 3e-6
    phi = np.linspace(0.0, 2.0 * np.pi, 3601)
    x, y = e + R * np.cos(phi), R * np.sin(phi)
    theta, dr = radial_deviation(x, y, (0.0, 0.0), R)
    assert dr.max() == pytest.approx(e, abs=1e-15)
    assert dr.min() == pytest.approx(-e, abs=1e-15)
    np.testing.assert_allclose(dr, e * np.cos(theta), rtol=0, atol=e * e / R)


def test_an_ellipse_reads_its_semi_axes_at_the_quadrant_points() -> None:
    # semi-axes R + d along X and R - d along Y: +d at 0 and 180 deg, -d at 90 and 270 deg,
    # d cos(2 theta) in between to first order in d / R
    d = 2e-6
    phi = np.deg2rad(np.arange(0.0, 360.0, 0.25))
    theta, dr = radial_deviation((R + d) * np.cos(phi), (R - d) * np.sin(phi), (0.0, 0.0), R)
    quadrants = {0: d, 360: -d, 720: d, 1080: -d}  # indices of 0, 90, 180, 270 deg
    for i, expected in quadrants.items():
        assert dr[i] == pytest.approx(expected, abs=1e-15)
    np.testing.assert_allclose(dr, d * np.cos(2.0 * theta), rtol=0, atol=2 * d * d / R)


@pytest.mark.parametrize(("kwargs", "exc", "names"), [
    ({"x": [0.0, np.nan]}, ValueError, "x contains NaN"),
    ({"y": [[0.0, 1.0]]}, ValueError, "y has shape"),
    ({"x": []}, ValueError, "x has shape"),
    ({"y": [0.0, 1.0, 2.0]}, ValueError, "x has 2 samples and y 3"),
    ({"x": ["a", "b"]}, TypeError, "x="),
    ({"center": (0.0,)}, ValueError, "center="),
    ({"center": (0.0, np.inf)}, ValueError, "center="),
    ({"center": "ab"}, TypeError, "center="),
    ({"radius": 0.0}, ValueError, "radius=0.0"),
    ({"radius": -1e-3}, ValueError, "radius=-0.001"),
    ({"radius": float("nan")}, ValueError, "radius=nan"),
    ({"radius": "1"}, TypeError, "radius='1'"),
    ({"radius": True}, TypeError, "radius=True"),
])
def test_bad_input_names_the_parameter(kwargs: dict[str, object], exc: type[Exception],
                                       names: str) -> None:
    args: dict[str, object] = {"x": [R, 0.0], "y": [0.0, R], "center": (0.0, 0.0), "radius": R}
    args.update(kwargs)
    with pytest.raises(exc, match=names.replace("(", r"\(")):
        radial_deviation(**args)  # type: ignore[arg-type]


def test_magnification_is_1_2_5_and_fills_at_most_30_percent() -> None:
    for dev in (3e-7, 1.7e-6, 4.2e-6, 17.9e-6, 55e-6):
        k = ballbar_magnification(dev, R)
        mantissa = k / 10.0 ** np.floor(np.log10(k))
        assert min(abs(mantissa - m) for m in (1.0, 2.0, 5.0)) < 1e-9
        assert 0.4 * 0.3 * R <= k * dev <= 0.3 * R * (1 + 1e-12)
    assert ballbar_magnification(0.0, R) == 1.0
    with pytest.raises(ValueError, match="max_deviation=-1e-06"):
        ballbar_magnification(-1e-6, R)
    with pytest.raises(ValueError, match="fill=1.5"):
        ballbar_magnification(1e-6, R, fill=1.5)
    with pytest.raises(ValueError, match="radius=0"):
        ballbar_magnification(1e-6, 0)


# --- circle_run on the circle trajectory -------------------------------------------------------

def test_circle_run_of_the_reference_shifted_reads_the_shift() -> None:
    ref = make_trajectory("circle", radius=R, feed=0.05, ts=1e-3)
    e = 5e-6
    run = circle_run(ref, ref.x + np.array([[e], [0.0]]))
    # the centre of circle() is (-R, 0); the shifted path is an offset circle
    assert run.center == (-R, 0.0) and run.radius == R
    m = run.moving
    np.testing.assert_allclose(run.deviation[m], e * np.cos(run.theta[m]), rtol=0,
                               atol=e * e / R)
    # "both": counter-clockwise out, clockwise back, at rest in the dwells
    assert set(np.unique(run.sense)) == {-1, 0, 1}
    ccw = np.flatnonzero(run.sense == 1)
    cw = np.flatnonzero(run.sense == -1)
    assert ccw.max() < cw.min()
    assert run.max_deviation == pytest.approx(e, rel=1e-6)


def test_circle_run_refuses_other_runs() -> None:
    ref = make_trajectory("s_curve", ts=1e-3)
    with pytest.raises(ValueError, match="needs a 'circle' run"):
        circle_run(ref, np.atleast_2d(ref.x))
    circ = make_trajectory("circle", radius=R, ts=1e-3)
    with pytest.raises(ValueError, match="position has shape"):
        circle_run(circ, circ.x[:, :-1])


# --- the picture -----------------------------------------------------------------------------

def _synthetic(peak: float, n: int = 2000) -> CircleRun:
    th = np.linspace(-np.pi, np.pi, n, endpoint=False)
    # a spike after each quadrant point, the shape of a quadrant glitch
    dev = peak * np.exp(-np.mod(th, np.pi / 2) / 0.05) - 1e-6
    return CircleRun(np.concatenate([th, th[::-1]]), np.concatenate([dev, 0.8 * dev[::-1]]),
                     np.concatenate([np.ones(n, int), -np.ones(n, int)]), R, (-R, 0.0))


def test_small_multiples_share_one_magnification_and_draw_r_plus_k_dr(tmp_path: Path) -> None:
    runs = {"none": _synthetic(18e-6), "a": _synthetic(6e-6), "b": _synthetic(2e-6)}
    fig, k = ballbar_figure(runs, "t", baseline="none")
    assert k == ballbar_magnification(max(r.max_deviation for r in runs.values()), R)
    polar = [ax for ax in fig.axes if ax.name == "polar"]
    assert len(polar) == 3
    for ax, (label, run) in zip(polar, runs.items(), strict=True):
        assert ax.get_title().startswith(label)
        lines = {str(ln.get_label()).split(":")[0]: ln for ln in ax.get_lines()}
        th, r_mm = (np.asarray(a) for a in lines["clockwise"].get_data())
        m = run.sense == -1
        np.testing.assert_allclose(th, run.theta[m])
        # plotted radius = R + k (r - R), in mm
        np.testing.assert_allclose((r_mm * 1e-3 - R) / k, run.deviation[m], rtol=1e-9,
                                   atol=1e-12)
        # the baseline behind every other panel, in grey
        assert ("none (both senses)" in lines) == (label != "none")
    assert any(f"magnified x{k:g}" in t.get_text() for t in fig.texts)
    path = tmp_path / "bb.png"
    assert plot_ballbar(runs, "t", path, baseline="none") == k
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_figure_refuses_what_it_cannot_draw() -> None:
    with pytest.raises(ValueError, match="runs="):
        ballbar_figure({}, "t")
    with pytest.raises(ValueError, match="baseline='none'"):
        ballbar_figure({"a": _synthetic(1e-6)}, "t", baseline="none")
    other = _synthetic(1e-6)
    other = CircleRun(other.theta, other.deviation, other.sense, 2 * R, other.center)
    with pytest.raises(ValueError, match="radii"):
        ballbar_figure({"a": _synthetic(1e-6), "b": other}, "t")
    with pytest.raises(ValueError, match="magnification=0"):
        ballbar_figure({"a": _synthetic(1e-6)}, "t", magnification=0)
    with pytest.raises(TypeError, match=r"runs\['a'\]"):
        ballbar_figure({"a": np.zeros(3)}, "t")  # type: ignore[dict-item]


@pytest.mark.parametrize("n_runs", [1, 3])
def test_ring_labels_lie_on_patches_above_the_rings_and_apart(n_runs: int) -> None:
    runs = {name: _synthetic(p) for name, p in zip("abc", (18e-6, 6e-6, 2e-6), strict=True)}
    fig, k = ballbar_figure(dict(list(runs.items())[:n_runs]), "t")
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    for ax in (a for a in fig.axes if a.name == "polar"):
        # no tick label to strike through: the rings carry no text of their own
        assert not any(t.get_text() for t in ax.get_yticklabels())
        labels = [t for t in ax.texts if t.get_gid() == "ring-label"]
        assert "0" in [t.get_text() for t in labels] and len(labels) >= 2
        rings = np.asarray(ax.get_yticks())
        top = max([ln.get_zorder() for ln in ax.get_lines()] + [ax.yaxis.get_zorder()])
        boxes = []
        for t in labels:
            assert t.get_zorder() > top
            patch = t.get_bbox_patch()
            assert patch is not None and patch.get_facecolor()[3] >= 0.85
            # centred on its ring
            assert np.min(np.abs(rings - t.get_position()[1])) < 1e-9
            boxes.append(patch.get_window_extent(renderer))
        for i, a in enumerate(boxes):
            assert not any(a.overlaps(b) for b in boxes[i + 1:])
