"""Reference trajectories: every registered id, plus the properties of each built-in."""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from fricbench.trajectories import Reference, make_trajectory, trajectory_registry
from fricbench.trajectories.segments import (
    concatenate,
    monotone_point_to_point,
    point_to_point,
    rest,
    reversal_accel_limit,
    windowed_sines,
)

IDS = trajectory_registry.ids()


@cache
def _default(id: str) -> Reference:
    return make_trajectory(id)


def _check_derivatives(ref: Reference) -> None:
    """v must be dx/dt and a dv/dt: central differences and running integrals agree.

    Central differences of ``v`` average ``a`` over two samples, so at a jerk step they can
    differ from the sampled ``a`` by up to half of one sample's change of ``a``: the tolerance
    on ``a`` includes that.
    """
    ts = ref.ts
    vmax = np.abs(ref.v).max()
    amax = np.abs(ref.a).max()
    xmax = np.abs(ref.x).max()
    dx = np.gradient(ref.x, ts, axis=-1)[..., 1:-1] - ref.v[..., 1:-1]
    dv = np.gradient(ref.v, ts, axis=-1)[..., 1:-1] - ref.a[..., 1:-1]
    step_a = np.abs(np.diff(ref.a, axis=-1)).max()
    assert np.abs(dx).max() <= 1e-2 * vmax
    assert np.abs(dv).max() <= 0.75 * step_a + 1e-2 * amax
    # x - x0 = int v dt,  v - v0 = int a dt
    iv = ref.v - ref.v[..., :1] - cumulative_trapezoid(ref.a, dx=ts, axis=-1, initial=0.0)
    ix = ref.x - ref.x[..., :1] - cumulative_trapezoid(ref.v, dx=ts, axis=-1, initial=0.0)
    assert np.abs(iv).max() <= 1e-2 * vmax
    assert np.abs(ix).max() <= 1e-3 * xmax


def _rest_runs(v: np.ndarray, min_len: int) -> int:
    """Number of runs of at least ``min_len`` samples at exactly zero velocity."""
    still = np.concatenate(([False], v == 0.0, [False]))
    edges = np.flatnonzero(np.diff(still.astype(int)))
    return int(np.sum(edges[1::2] - edges[::2] >= min_len))


def _reversals(v: np.ndarray) -> tuple[int, int]:
    """(all velocity sign changes, those without a sample at rest in between)."""
    nz = np.flatnonzero(np.abs(v) > 1e-12)
    sign = np.sign(v[nz])
    change = sign[1:] != sign[:-1]
    direct = change & (np.diff(nz) == 1)
    return int(change.sum()), int(direct.sum())


# -- every registered id -------------------------------------------------------------------
@pytest.mark.parametrize("id", IDS)
def test_shapes_time_and_rest(id: str) -> None:
    ref = _default(id)
    assert isinstance(ref, Reference)
    assert ref.name == id
    assert isinstance(ref.params, dict) and "ts" in ref.params
    k = ref.n_samples
    assert k > 100
    for arr in (ref.x, ref.v, ref.a):
        assert arr.shape == ref.x.shape and arr.shape[-1] == k
        assert np.all(np.isfinite(arr))
    assert ref.t[0] == 0.0
    np.testing.assert_allclose(np.diff(ref.t), ref.ts, rtol=1e-9)
    np.testing.assert_array_equal(ref.v[..., 0], 0.0)
    np.testing.assert_array_equal(ref.a[..., 0], 0.0)
    np.testing.assert_allclose(ref.v[..., -1], 0.0, atol=1e-12)


@pytest.mark.parametrize("id", IDS)
def test_derivatives_consistent(id: str) -> None:
    _check_derivatives(_default(id))


@pytest.mark.parametrize("id", IDS)
def test_deterministic(id: str) -> None:
    a, b = _default(id), make_trajectory(id)
    for nm in ("t", "x", "v", "a"):
        np.testing.assert_array_equal(getattr(a, nm), getattr(b, nm))
    assert a.params == b.params


@pytest.mark.parametrize("id", IDS)
@pytest.mark.parametrize("ts", [0.0, -1e-3, 0.5, float("nan")])
def test_bad_ts_names_parameter(id: str, ts: float) -> None:
    with pytest.raises(ValueError, match="ts"):
        make_trajectory(id, ts=ts)


@pytest.mark.parametrize("id", IDS)
def test_unknown_keyword_rejected(id: str) -> None:
    with pytest.raises(TypeError):
        make_trajectory(id, no_such_parameter=1.0)


@pytest.mark.parametrize("id", IDS)
def test_coarser_sample_time(id: str) -> None:
    ref = make_trajectory(id, ts=2e-3)
    assert ref.ts == pytest.approx(2e-3)
    assert ref.duration == pytest.approx(_default(id).duration, abs=2e-3)


# -- bad parameters of the built-ins ---------------------------------------------------------
BAD: list[tuple[str, dict[str, Any], str]] = [
    ("m_serial", {"stroke": 0.0}, "stroke"),
    ("m_serial", {"feed": -0.01}, "feed"),
    ("m_serial", {"accel": 0.0}, "accel"),
    ("m_serial", {"jerk": float("inf")}, "jerk"),
    ("m_serial", {"dwell": -0.1}, "dwell"),
    ("m_serial", {"stroke_scales": ()}, "stroke_scales"),
    ("m_serial", {"feed_scales": (1.0, 0.5)}, "feed_scales"),
    ("m_serial", {"feed_scales": (1.0, -0.5, 0.2)}, "feed_scales"),
    ("curve", {"amplitudes": (0.01, -0.004, 0.001)}, "amplitudes"),
    ("curve", {"frequencies": (0.1, 0.2)}, "frequencies"),
    ("curve", {"phases": (0.0, float("nan"), 0.0)}, "phases"),
    ("curve", {"duration": 0.0}, "duration"),
    ("curve", {"ramp": 10.0}, "ramp"),
    ("circle", {"radius": 0.0}, "radius"),
    ("circle", {"feed": 0.0}, "feed"),
    ("circle", {"direction": "up"}, "direction"),
    ("circle", {"revolutions": -1.0}, "revolutions"),
    ("circle", {"jerk": -1.0}, "jerk"),
    ("reversal_sine", {"amplitudes": (1e-4, 0.0)}, "amplitudes"),
    ("reversal_sine", {"frequencies": ()}, "frequencies"),
    ("reversal_sine", {"cycles": 0}, "cycles"),
    ("reversal_sine", {"ramp_cycles": 0.0}, "ramp_cycles"),
    ("s_curve", {"distance": 0.0}, "distance"),
    ("s_curve", {"feed": 0.0}, "feed"),
    ("s_curve", {"accel": -1.0}, "accel"),
    ("s_curve", {"dwell": -1.0}, "dwell"),
    ("random", {"duration": 0.0}, "duration"),
    ("random", {"seed": -1}, "seed"),
    ("random", {"feed_range": (0.05, 0.001)}, "feed_range"),
    ("random", {"length_range": (1e-4, 0.1)}, "length_range"),
    ("random", {"x_limit": 0.0}, "x_limit"),
]


@pytest.mark.parametrize(("id", "kwargs", "name"), BAD)
def test_bad_parameter_names_it(id: str, kwargs: dict[str, Any], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        make_trajectory(id, **kwargs)


@pytest.mark.parametrize(
    ("id", "kwargs", "name"),
    [("reversal_sine", {"cycles": 2.5}, "cycles"), ("random", {"seed": "0"}, "seed"),
     ("s_curve", {"back": 1}, "back"), ("curve", {"amplitudes": "abc"}, "amplitudes")],
)
def test_wrong_type_names_it(id: str, kwargs: dict[str, Any], name: str) -> None:
    with pytest.raises(TypeError, match=name):
        make_trajectory(id, **kwargs)


# -- properties of each built-in -------------------------------------------------------------
def test_m_serial_stops_and_reversals() -> None:
    ref = _default("m_serial")
    dwell = ref.params["dwell"]
    stops = _rest_runs(ref.v, int(0.9 * dwell / ref.ts))
    reversals, direct = _reversals(ref.v)
    assert stops >= 2
    assert reversals >= 2
    assert direct >= 2  # velocity crosses zero without a stop
    assert 10.0 <= ref.duration <= 20.0
    assert ref.x[0] == 0.0 and ref.x[-1] == 0.0
    assert ref.x.min() >= -1e-12 and ref.x.max() <= ref.params["stroke"] + 1e-12
    assert np.abs(ref.v).max() <= ref.params["feed"] * (1 + 1e-9)
    assert np.abs(ref.a).max() <= ref.params["accel"] * (1 + 1e-9)


def test_m_serial_short_strokes_still_valid() -> None:
    ref = make_trajectory("m_serial", stroke=2e-4, feed=0.05, accel=2.0, jerk=100.0)
    _check_derivatives(ref)
    assert ref.x.min() >= -1e-12 and ref.x.max() <= 2e-4 + 1e-12


def test_curve_geometry() -> None:
    ref = _default("curve")
    reversals, direct = _reversals(ref.v)
    assert reversals >= 5 and direct == reversals
    assert 0.01 <= np.abs(ref.x).max() <= 0.02
    assert 0.02 <= np.abs(ref.v).max() <= 0.04
    assert ref.x[0] == 0.0 and abs(ref.x[-1]) < 1e-12
    crossing = np.flatnonzero(np.sign(ref.v[1:]) * np.sign(ref.v[:-1]) < 0)
    acc = np.abs(ref.a[crossing])
    assert acc.min() > 0.0 and acc.max() > 2.0 * acc.min()  # different accelerations


def test_reversal_sine_includes_sub_100um_blocks() -> None:
    ref = _default("reversal_sine")
    assert min(ref.params["amplitudes"]) < 1e-4
    # peak |x| of each block between rests
    moving = ref.v != 0.0
    edges = np.flatnonzero(np.diff(np.concatenate(([0], moving.astype(int), [0]))))
    peaks = [np.abs(ref.x[s:e]).max() for s, e in zip(edges[::2], edges[1::2], strict=True)]
    assert len(peaks) == len(ref.params["amplitudes"]) * len(ref.params["frequencies"])
    assert 0.0 < min(peaks) < 1e-4
    np.testing.assert_allclose(sorted(peaks)[-1], max(ref.params["amplitudes"]), rtol=1e-3)


@pytest.mark.parametrize("direction", ["ccw", "cw", "both"])
def test_circle(direction: str) -> None:
    ref = make_trajectory("circle", direction=direction, ts=2e-3)
    r = ref.params["radius"]
    assert ref.n_axes == 2 and ref.x.shape == (2, ref.n_samples)
    np.testing.assert_array_equal(ref.x[:, 0], 0.0)
    np.testing.assert_allclose(np.hypot(ref.x[0] + r, ref.x[1]), r, rtol=1e-12)
    # angular momentum about the centre: > 0 counter-clockwise, < 0 clockwise
    h = (ref.x[0] + r) * ref.v[1] - ref.x[1] * ref.v[0]
    assert (h.max() > 1e-9) == (direction in ("ccw", "both"))
    assert (h.min() < -1e-9) == (direction in ("cw", "both"))
    for i in range(2):  # each axis reverses at a quadrant crossing
        assert _reversals(ref.v[i])[0] >= 1
    assert ref.axis(1).x.shape == (ref.n_samples,)
    _check_derivatives(ref)


def test_s_curve_one_way_and_negative() -> None:
    ref = make_trajectory("s_curve", distance=-0.01, back=False)
    assert ref.x[-1] == -0.01 and ref.x.max() <= 1e-15
    assert np.abs(ref.v).max() <= ref.params["feed"] * (1 + 1e-9)
    assert np.abs(ref.a).max() <= ref.params["accel"] * (1 + 1e-9)
    _check_derivatives(ref)


def test_random_seeds() -> None:
    a = _default("random")
    b = make_trajectory("random", seed=0)
    c = make_trajectory("random", seed=1)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.a, b.a)
    assert a.x.shape == c.x.shape  # same duration, different content
    assert not np.array_equal(a.x, c.x)
    assert a.duration == pytest.approx(a.params["duration"], abs=a.ts)
    assert a.x[-1] == 0.0


@pytest.mark.parametrize("seed", range(1, 6))
def test_random_many_seeds_valid(seed: int) -> None:
    ref = make_trajectory("random", seed=seed, duration=8.0)
    _check_derivatives(ref)
    assert np.abs(ref.x).max() <= ref.params["x_limit"] + 1e-9
    assert np.abs(ref.v).max() <= 1.5 * ref.params["feed_range"][1] * (1 + 1e-9)


def test_random_differs_from_evaluation_set() -> None:
    ref = _default("random")
    for id in ("m_serial", "curve", "reversal_sine", "s_curve"):
        other = _default(id)
        k = min(ref.n_samples, other.n_samples)
        assert not np.allclose(ref.x[:k], other.x[:k])


# -- building blocks -------------------------------------------------------------------------
def test_concatenate_rejects_gaps() -> None:
    with pytest.raises(ValueError, match="segments"):
        concatenate([rest(0.0, 0.1), rest(1e-3, 0.1)], 1e-3)
    with pytest.raises(ValueError, match="segments"):
        concatenate([], 1e-3)


def test_point_to_point_limits() -> None:
    lim = reversal_accel_limit(0.01, 20.0)
    with pytest.raises(ValueError, match="a1"):
        point_to_point(0.0, 0.01, 0.01, 1.0, 20.0, a1=-1.1 * lim)
    seg = monotone_point_to_point(0.0, 5e-5, 0.02, 0.5, 20.0, a1=-0.5)
    assert 0.0 - 1e-12 <= seg.bounds[0] and seg.bounds[1] <= 5e-5 + 1e-12
    assert seg.end[0] == pytest.approx(5e-5)


def test_windowed_sines_rejects_long_ramp() -> None:
    with pytest.raises(ValueError, match="ramp"):
        windowed_sines((1e-3,), (1.0,), (0.0,), 1.0, 0.6)
