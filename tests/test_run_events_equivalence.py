"""Old detectors against the one event finder on random signals (removed once callers switch)."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.bench.metrics import reversal_indices
from fricbench.run_events import (
    hysteresis_sign,
    motion_events,
    motion_sign,
    sign_reversals,
)
from fricbench.sysid.diagnose.report import _aligned
from fricbench.sysid.diagnose.signals import reversal_mask
from fricbench.sysid.friction_error import find_events, reference_velocity
from fricbench.sysid.io import _count_reversals


def _signals(seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    k = 3000
    t = np.arange(k) * 1e-3
    # a velocity with dwells (exact zeros), near-zero crossings and noise
    v = np.sin(2 * np.pi * rng.uniform(0.5, 3.0) * t) + rng.normal(0, 0.05, k)
    v[rng.random(k) < 0.1] = 0.0
    dwell = np.repeat(rng.random(k // 50) < 0.3, 50)
    v = np.where(dwell, 0.0, v) * rng.uniform(0.01, 0.2)
    small = rng.normal(0, 1e-6, k) * (rng.random(k) < 0.5)
    return [v, v + small, np.round(v * 200) / 200, rng.normal(0, 1e-6, k)]


@pytest.mark.parametrize("seed", range(12))
def test_old_and_new_agree(seed: int) -> None:
    ts = 1e-3
    n_events = n_rev = 0
    for v in _signals(seed):
        x = np.cumsum(v) * ts
        for tol in (1e-7, 1e-6, 1e-3):
            for gap in (0, 2, 5):
                vv, _ = reference_velocity(x, ts)
                old = find_events(x, ts, v_tol=tol, max_gap=gap)
                new = motion_events(vv, ts, rest_speed=tol, max_gap=gap)
                assert [(e.kind, e.index, e.direction, e.accel) for e in old] == [
                    (e.kind, e.index, e.direction, e.accel) for e in new]
                n_events += len(old)
            old_r = reversal_indices(v, ts, tol)
            new_r = sign_reversals(motion_sign(v, tol))
            assert np.array_equal(old_r, new_r)
            via_events = [e.onset for e in motion_events(v, ts, rest_speed=tol, max_gap=None)
                          if e.kind == "reversal"]
            assert list(new_r) == via_events
            n_rev += len(old_r)
        # rest_speed 0: the report's alignment and the diagnosis' reversal mask
        flips = sign_reversals(motion_sign(v, 0.0))
        mask = np.zeros(v.shape[0], dtype=bool)
        for i in flips:
            mask[i:i + 100] = True
        assert np.array_equal(reversal_mask(v, ts, 0.1), mask)
        rb = np.cumsum(np.random.default_rng(seed).normal(size=v.shape[0]))
        wb, _, _ = _aligned(rb, rb, v, ts)
        i0, i1 = int(0.05 / ts), int(0.3 / ts)
        ok = [i for i in flips[:200] if i - i0 >= 0 and i + i1 <= v.shape[0]]
        assert len(wb) == len(ok)
        for w, i in zip(wb, ok, strict=True):
            assert np.array_equal(w, np.sign(v[i]) * (rb[i - i0:i + i1] - rb[i - i0]))
        # the loader's hysteresis count
        for tol in (1e-6, 1e-4, 1e-3 * max(float(np.ptp(x)), 1e-9)):
            for step in (1, 3):
                assert _count_reversals(x, 1e-3 / step, tol) == sign_reversals(
                    hysteresis_sign(x[::step], tol)).size
    assert n_events > 0 and n_rev > 0


@pytest.mark.parametrize("seed", range(12))
def test_feature_turning_points_agree(seed: int) -> None:
    from fricbench.predictors.features import _last_true
    ts = 1e-3
    for v in _signals(seed):
        for tol in (0.0, 1e-6, 1e-3):
            # predictors/features.py before the change
            sgn = np.where(np.abs(v) > tol, np.sign(v), 0.0)
            moving = sgn != 0.0
            last_move = _last_true(moving)
            direction = np.where(last_move >= 0, sgn[np.maximum(last_move, 0)], 0.0)
            prev_moving = np.concatenate([[False], moving[:-1]])
            prev_dir = np.concatenate([[0.0], direction[:-1]])
            turn = moving & (~prev_moving | (direction != prev_dir))
            new = np.zeros(v.shape[0], dtype=bool)
            new[[e.onset for e in motion_events(v, ts, rest_speed=tol, max_gap=0)
                 if e.kind != "stop"]] = True
            assert np.array_equal(turn, new)
            assert np.array_equal(sgn, motion_sign(v, tol))
