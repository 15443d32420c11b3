"""The leaderboard's error budget: the uncompensated error with friction and with it off."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.axis import simulate
from fricbench.bench.error_budget import error_budget, frictionless, header_lines
from fricbench.gym import get_spec
from fricbench.trajectories import make_trajectory


def test_frictionless_axis_has_no_friction_force() -> None:
    axis = frictionless(get_spec("fricbench/EMPS-v0").axis)
    assert axis.mechanics.damping == 0.0 and axis.mechanics.load == 0.0
    e = axis.effects
    assert (e.cogging_amplitude, e.friction_gradient, e.viscous_asymmetry,
            e.friction_variation, e.coulomb_asymmetry) == (0.0,) * 5
    assert e.quantization == get_spec("fricbench/EMPS-v0").axis.effects.quantization
    res = simulate(axis, make_trajectory("reversal_sine"))
    assert np.max(np.abs(res.friction)) < 1e-9  # N: rounding of the plant's force sum


def test_emps_error_is_the_lag_of_its_p_loop() -> None:
    """A P loop without feedforward lags v / kp behind a ramp: 0.0997 m/s / 160.18 1/s =
    622 um on the twin's m_serial; friction adds a few percent."""
    (b,) = error_budget("fricbench/EMPS-v0", ["m_serial"])
    lag = 0.0997 / 160.18
    assert b.max_frictionless == pytest.approx(lag, rel=0.05)
    assert 0.0 < b.friction_share < 0.1
    (p,) = error_budget("fricbench/PaperAxis-v0", ["m_serial"])
    assert p.friction_share > 0.5  # a cascade with feedforward: mostly friction


def test_header_lines() -> None:
    lines = header_lines("fricbench/EMPS-v0", ["m_serial"], ["none", "rl-residual"])
    assert "friction adds" in lines[0] and "m_serial" in lines[0]
    assert any("`kalman` alone" in line for line in lines[1:])
    assert len(header_lines("fricbench/PaperAxis-v0", ["m_serial"], ["rl-residual"])) == 1
    assert header_lines("fricbench/NoSuchEnv-v0", ["m_serial"], ["none"]) == []


def test_a_loop_unstable_without_its_damping_keeps_it() -> None:
    """The DC motor's identified PID law is unstable on the bare mass: the budget keeps the
    damping and the header says so."""
    axis = get_spec("fricbench/DCMotor-v0").axis
    with pytest.raises(ValueError, match="unstable"):
        frictionless(axis)
    (b,) = error_budget("fricbench/DCMotor-v0", ["reversal_sine"])
    assert b.damping_kept and b.max_frictionless > 0.0
    lines = header_lines("fricbench/DCMotor-v0", ["reversal_sine"], ["rl-residual"])
    assert "damping kept" in lines[0] and "`kalman` alone" in lines[1]
