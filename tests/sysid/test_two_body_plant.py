"""fricbench's two-body backlash plant against the independent second simulator.

The second simulator (``second_sim.py``, its own integrator) couples motor and table through a
gap with a stiff spring-damper contact; fricbench's plant makes the contact rigid and the impact
inelastic. Driven open loop by the second simulator's own force, from its state shortly before
each reversal of the table, the plant must follow the table there far better than the play
operator (the table stopping the instant the motor leaves it, friction on the motor).
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

from fricbench.axis import plant as PL

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import second_sim as S  # noqa: E402

TS = S.LOOP_TS
WINDOW = 150  # samples after each start (150 ms at 1 kHz)


def _row(plant: S.Plant, share: float) -> np.ndarray:
    p = PL.default_row(plant.mass, plant.damping, TS, S.SUBSTEPS)
    p[PL.FC] = plant.coulomb
    p[PL.FS_EXCESS] = max(plant.breakaway - plant.coulomb, 0.0)
    p[PL.VS] = plant.stribeck_velocity
    p[PL.DELTA] = plant.stribeck_shape
    p[PL.BACKLASH] = plant.backlash
    p[PL.BL_LOAD] = share
    return p


def _window_rms(p: np.ndarray, trace: S.Trace, k0: int) -> float:
    """Rms table error over a window from the second simulator's state at sample ``k0``."""
    c = PL.constants(p)
    xm, xt = trace.x_motor, trace.x_table
    x, v = xm[k0], (xm[k0] - xm[k0 - 1]) / TS
    half = 0.5 * float(p[PL.BACKLASH])
    d = min(max(xt[k0] - xm[k0], -half), half)
    dv = (xt[k0] - xt[k0 - 1]) / TS - v
    z = theta = 0.0
    x_play = x
    err = np.empty(WINDOW)
    for j, k in enumerate(range(k0, k0 + WINDOW)):
        x, v, z, x_play, d, dv, theta, _ = PL.advance(c, x, v, z, x_play, d, dv, theta,
                                                       trace.force[k])
        err[j] = x_play + d - xt[k + 1]
    return float(np.sqrt(np.mean(err**2)))


@pytest.mark.parametrize("seed", [1, 3, 5])
def test_the_two_body_plant_follows_the_independent_simulator_through_reversals(
        seed: int) -> None:
    case = S.draw_case("backlash", seed)
    plant, trace = case.plant, case.clean
    assert trace.force.shape == trace.x_table.shape
    vt = np.diff(trace.x_table)
    rev = np.flatnonzero((np.sign(vt[1:]) != np.sign(vt[:-1])) & (np.abs(vt[1:]) > 1e-7))
    starts = [k - 20 for k in rev if 100 < k < trace.x_table.size - WINDOW - 20][:20]
    assert starts, "the drawn run has no reversal of the table"
    two_body = np.mean([_window_rms(_row(plant, 1.0 - plant.motor_share), trace, k)
                        for k in starts])
    play = np.mean([_window_rms(_row(plant, 0.0), trace, k) for k in starts])
    assert np.isfinite(two_body)
    # measured on seeds 1..5: 3 to 35 times closer than the play operator, within 1..10 % of
    # the gap
    assert two_body < 0.3 * play, (two_body, play)
    assert two_body < 0.15 * plant.backlash, (two_body, plant.backlash)
