"""The sampled linear loop's stability, checked when an Axis is built (issue 14 item 13)."""

from __future__ import annotations

import control
import numpy as np
import pytest

from fricbench.axis import Axis, AxisBatch, SimulationDivergedError, simulate
from fricbench.axis import kernel as K
from fricbench.axis.linear import sampled_closed_loop, spectral_radius
from fricbench.trajectories import make_trajectory


@pytest.fixture(scope="module")
def s_curve():
    return make_trajectory("s_curve")


@pytest.mark.parametrize("section,changes,named", [
    # the three settings that ran whole episodes bounded by the current saturation
    ("mechanics", {"mass": 1e-9}, "mechanics.mass=1e-09 kg"),
    ("controller", {"kp": 1e6}, "controller.kp=1e+06 1/s"),
    ("controller", {"kv": 1e4}, "controller.kv=10000 A s/m"),
    # two samples of actuator delay are too many for the default gains
    ("effects", {"delay_samples": 2}, "effects.delay_samples=2"),
    ("controller", {"ts": 0.01}, "controller.ts=0.01 s"),
])
def test_unstable_settings_are_refused_naming_the_parameter(section, changes, named) -> None:
    with pytest.raises(ValueError, match=r"the sampled closed loop is unstable \(pole \|z\|=") \
            as info:
        getattr(Axis(), f"with_{section}")(**changes)
    msg = str(info.value)
    assert msg.startswith(named)
    assert "(the default) gives |z|=0.95" in msg
    # the other loop parameters are given by value
    assert "damping=200 N s/m" in msg


def test_from_dict_refuses_an_unstable_axis_and_names_all_changed_parameters() -> None:
    with pytest.raises(ValueError, match=r"^controller\.kv=2000 A s/m, mechanics\.mass=100 kg "
                                         r"with kp=180.*together give a stable loop"):
        Axis.from_dict({"controller": {"kv": 2000.0}, "mechanics": {"mass": 100.0}})


@pytest.mark.parametrize("delay", [0, 1])
def test_sampled_closed_loop_is_the_kernel(s_curve, delay: int) -> None:
    """Friction off, the python-control loop the check uses is the kernel's own map."""
    axis = Axis().without_friction().with_effects(delay_samples=delay)
    res = simulate(axis, s_curve)
    z = np.zeros_like(s_curve.t)
    resp = control.forced_response(sampled_closed_loop(axis), T=s_curve.t,
                                   U=np.vstack([s_curve.x, s_curve.v, s_curve.a, z, z]))
    assert np.max(np.abs(resp.outputs - res.x_true)) < 1e-12


def test_check_agrees_with_the_kernel_on_both_sides_of_the_boundary(s_curve) -> None:
    """kv = 1100 is stable and runs bounded without a current limit; kv = 1150 is refused, and
    the kernel run with those gains (packed by hand, past the check) does diverge."""
    rows = (lambda a: np.ascontiguousarray(np.atleast_2d(a)))
    stable = Axis().with_controller(kv=1100.0, i_max=1e9)
    assert spectral_radius(stable) < 1.0
    res = simulate(stable, s_curve)
    assert np.max(np.abs(res.error)) < 1e-4
    with pytest.raises(ValueError, match="controller.kv=1150"):
        stable.with_controller(kv=1150.0)
    batch = AxisBatch(stable)
    batch.P[:, K.P_KV] = 1150.0
    batch.reset(s_curve.x[0])
    with pytest.raises(SimulationDivergedError, match="runaway"):
        batch.run(rows(s_curve.x), rows(s_curve.v), rows(s_curve.a))


@pytest.mark.parametrize("changes", [
    {"kp": 0.0, "kvff": 0.0, "kv": 0.0, "ti": 0.0},  # controller off: the force is the input
    {"kp": 0.0},
    {"ti": 0.0},
])
def test_loops_with_poles_on_the_unit_circle_construct(changes) -> None:
    axis = Axis().with_controller(**changes)
    assert spectral_radius(axis) == pytest.approx(1.0, abs=1e-6)


def test_friction_does_not_enter_the_check() -> None:
    base = spectral_radius(Axis())
    for fid in ("lugre", "coulomb", "viscous"):
        assert spectral_radius(Axis().with_friction(fid)) == base
