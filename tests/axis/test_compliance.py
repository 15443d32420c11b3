"""The compliant (two-mass) axis in the one plant (issue 13 item 3)."""

from __future__ import annotations

import os
import sys

import control
import numpy as np
import pytest

from fricbench.axis import Axis, AxisBatch, simulate
from fricbench.axis import kernel as K
from fricbench.axis import plant as PL
from fricbench.axis.linear import sampled_closed_loop
from fricbench.trajectories import make_trajectory

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from plant_runs import open_loop as _open_loop  # noqa: E402


@pytest.fixture(scope="module")
def s_curve():
    return make_trajectory("s_curve")


def _row(mass: float, ratio: float, f_r: float, zeta: float, ts: float = 1e-3,
         n_sub: int = 5) -> np.ndarray:
    p = PL.default_row(mass, 0.0, ts, n_sub)
    p[PL.COMP_RATIO], p[PL.COMP_FREQ], p[PL.COMP_ZETA] = ratio, f_r, zeta
    return p


def _peak_hz(x: np.ndarray, ts: float) -> float:
    """Frequency of the largest spectral peak of a decaying response (zero padding, parabolic
    fit on the log magnitude; no window: the response decays within the record)."""
    xw = x - x.mean()
    n_fft = 16 * x.size
    mag = np.abs(np.fft.rfft(xw, n_fft))
    k = int(np.argmax(mag[1:])) + 1
    a, b, c = np.log(mag[k - 1:k + 2])
    return (k + 0.5 * (a - c) / (a - 2 * b + c)) / (n_fft * ts)


def test_compliance_off_is_the_rigid_axis_bit_for_bit(s_curve) -> None:
    """A zero load fraction ignores the other compliance entries: the rigid axis exactly."""
    base = Axis().with_effects(noise_std=1e-7, backlash=2e-6, cogging_amplitude=10.0)
    off = base.with_effects(compliance_frequency=13.0, compliance_damping=0.7)
    a, b = simulate(base, s_curve, seed=4), simulate(off, s_curve, seed=4)
    for name in ("x", "x_true", "u", "friction"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert sampled_closed_loop(base).nstates == sampled_closed_loop(off).nstates


@pytest.mark.parametrize("side", ["motor", "load"])
@pytest.mark.parametrize("measurement", ["motor", "table"])
def test_sampled_closed_loop_is_the_kernel_with_compliance(s_curve, measurement: str,
                                                           side: str) -> None:
    """Friction off, the stability check's loop is the compliant kernel's own map (its output
    is the fed-back side: logged here from the same side), the damping on either body."""
    # a soft loop (the full-closed loop of a compliant axis needs low gains)
    axis = Axis.from_dict({"controller": {"kp": 5.0, "kv": 10.0, "ti": 0.3}}).without_friction(
        ).with_effects(compliance_load_fraction=0.4, compliance_frequency=35.0,
                       compliance_damping=0.05, measurement=measurement,
                       compliance_friction=side)
    batch = AxisBatch(axis)
    batch.P[:, K.P_LOG_MOTOR] = 1.0 if measurement == "motor" else 0.0
    batch.reset(s_curve.x[0])
    rows = (lambda a: np.ascontiguousarray(np.atleast_2d(a)))
    _, x_logged, _, _ = batch.run(rows(s_curve.x), rows(s_curve.v), rows(s_curve.a))
    z = np.zeros_like(s_curve.t)
    resp = control.forced_response(sampled_closed_loop(axis), T=s_curve.t,
                                   U=np.vstack([s_curve.x, s_curve.v, s_curve.a, z, z]))
    assert np.max(np.abs(resp.outputs - x_logged[0])) < 1e-10 * np.ptp(s_curve.x)


def test_stiff_coupling_tends_to_the_rigid_axis() -> None:
    ts, n = 1e-3, 2000
    force = 100.0 * np.sin(2 * np.pi * 3.0 * np.arange(n) * ts)
    rigid, _ = _open_loop(_row(10.0, 0.0, 50.0, 0.05), force, ts, 5)
    gaps = []
    for f_r in (1e2, 1e3, 1e4, 1e5):
        table, motor = _open_loop(_row(10.0, 0.5, f_r, 0.05), force, ts, 5)
        gaps.append(max(np.max(np.abs(table - rigid)), np.max(np.abs(motor - rigid))))
    # the deflection falls as 1 / f_r^2 (the load's inertia force over the stiffness): at least
    # 20 times per decade of stiffness
    assert all(g2 < 0.05 * g1 for g1, g2 in zip(gaps, gaps[1:], strict=False))
    assert gaps[-1] < 1e-9 * np.ptp(rigid)


def test_resonance_matches_the_formula() -> None:
    """Impulse response of the free two-mass axis: its peak at f_r within 2 % (random draws)."""
    rng = np.random.default_rng(2026)
    ts = 1e-3
    for _ in range(6):
        ratio = rng.uniform(0.1, 0.8)
        f_r = rng.uniform(10.0, 150.0)
        zeta = rng.uniform(0.005, 0.05)
        mass = rng.uniform(1.0, 500.0)
        force = np.zeros(8000)
        force[5] = mass
        table, motor = _open_loop(_row(mass, ratio, f_r, zeta), force, ts, 5)
        f_meas = _peak_hz((table - motor)[10:], ts)
        assert abs(f_meas / f_r - 1.0) < 0.02, (ratio, f_r, zeta, f_meas)


def test_linear_two_mass_is_exact_for_a_held_force() -> None:
    """Friction off, the compliant plant is the zero-order-hold discretisation of the
    two-mass ODE (scipy's), to rounding, at one substep per sample."""
    _check_held_force_zoh(side=0.0, seed=7, damping_low=0.0)


def _check_held_force_zoh(side: float, seed: int, damping_low: float,
                          motor_share: float = 0.0) -> None:
    """The open-loop compliant plant, friction off, the friction's side ``side`` (the damping
    B with it, but for ``motor_share`` of it on the motor when on the load), against scipy's
    zero-order-hold discretisation of the two-mass ODE, to 1e-9 of the motion, at one substep
    per sample (three random axes)."""
    from scipy.signal import cont2discrete, dlsim

    rng = np.random.default_rng(seed)
    ts, n = 1e-3, 3000
    for _ in range(3):
        mass, ratio = rng.uniform(1.0, 500.0), rng.uniform(0.1, 0.8)
        f_r, zeta = rng.uniform(10.0, 300.0), rng.uniform(0.0, 0.1)
        damp = rng.uniform(damping_low, 5)
        row = _row(mass, ratio, f_r, zeta, ts, 1)
        row[PL.B] = damp * mass
        row[PL.COMP_LOAD] = side
        row[PL.COMP_B_MOTOR] = motor_share
        force = mass * rng.standard_normal(n)
        table, motor = _open_loop(row, force, ts, 1)
        m_l = ratio * mass
        m_m = mass - m_l
        mu = m_m * m_l / mass
        w = 2 * np.pi * f_r
        k, c = mu * w * w, 2 * zeta * mu * w
        b_m, b_l = ((motor_share * damp * mass, (1.0 - motor_share) * damp * mass) if side
                    else (damp * mass, 0.0))
        a = np.array([[0, 1, 0, 0], [-k / m_m, -(c + b_m) / m_m, k / m_m, c / m_m],
                      [0, 0, 0, 1], [k / m_l, c / m_l, -k / m_l, -(c + b_l) / m_l]])
        b = np.array([[0.0], [1.0 / m_m], [0.0], [0.0]])
        cm = np.array([[0.0, 0, 1, 0], [1, 0, 0, 0]])
        ad, bd, cd, dd, _ = cont2discrete((a, b, cm, np.zeros((2, 1))), ts, "zoh")
        _, y, _ = dlsim((ad, bd, cd, dd, ts), force)
        scale = np.ptp(y[:, 0])
        assert np.max(np.abs(table - y[:, 0])) < 1e-9 * scale
        assert np.max(np.abs(motor - y[:, 1])) < 1e-9 * scale


def test_friction_side_on_the_load_is_exact_for_a_held_force() -> None:
    """Friction off, the friction's side on the load (the damping B with it): the
    zero-order-hold discretisation of the two-mass ODE with B on the load (scipy's), to
    rounding, at one substep per sample."""
    _check_held_force_zoh(side=1.0, seed=11, damping_low=0.1)


@pytest.mark.parametrize("motor_share", [0.3, 1.0])
def test_damping_split_between_the_bodies_is_exact_for_a_held_force(motor_share: float) -> None:
    """Friction on the load, a share of the damping B on the motor (its bearings): the
    zero-order-hold discretisation of the two-mass ODE with B split so (scipy's), to rounding."""
    _check_held_force_zoh(side=1.0, seed=13, damping_low=0.1, motor_share=motor_share)


def test_damping_share_is_ignored_with_the_friction_on_the_motor() -> None:
    """The share only moves B with the friction on the load: on the motor side it changes
    nothing, bit for bit."""
    row = _row(20.0, 0.4, 80.0, 0.03, 1e-3, 2)
    row[PL.B] = 30.0
    force = 20.0 * np.random.default_rng(3).standard_normal(500)
    base = _open_loop(row, force, 1e-3, 2)
    row[PL.COMP_B_MOTOR] = 0.7
    moved = _open_loop(row, force, 1e-3, 2)
    assert all(np.array_equal(a, b) for a, b in zip(base, moved, strict=True))


def _friction_row(ratio: float, f_r: float, n_sub: int, side: float) -> np.ndarray:
    p = _row(10.0, ratio, f_r, 0.05, 1e-3, n_sub)
    p[PL.B], p[PL.FC], p[PL.FS_EXCESS], p[PL.VS] = 20.0, 60.0, 20.0, 0.01
    p[PL.COMP_LOAD] = side
    return p


def test_friction_on_the_load_tends_to_the_rigid_axis() -> None:
    """Stick-slip with the friction on the load: a stiffer coupling (its resonance resolved by
    the substeps) gives the rigid axis with the same friction, as the motor side's does."""
    ts, n = 1e-3, 3000
    force = 100.0 * np.sin(2 * np.pi * 3.0 * np.arange(n) * ts)
    rigid, _ = _open_loop(_friction_row(0.0, 50.0, 5, 0.0), force, ts, 5)
    assert np.mean(np.diff(rigid) == 0.0) > 0.1  # it sticks
    gaps = []
    for f_r, n_sub in ((30.0, 5), (300.0, 50), (3000.0, 500)):
        table, motor = _open_loop(_friction_row(0.5, f_r, n_sub, 1.0), force, ts, n_sub)
        gaps.append(max(np.max(np.abs(table - rigid)), np.max(np.abs(motor - rigid))))
    assert all(g2 < 0.3 * g1 for g1, g2 in zip(gaps, gaps[1:], strict=False)), gaps
    assert gaps[-1] < 2e-3 * np.ptp(rigid), gaps


def test_friction_on_the_load_holds_the_load() -> None:
    """A force below the breakaway level, on a compliant axis with the friction on the load:
    the load stays where it is (to 1e-3 of the deflection), the motor settles at the spring's
    deflection ``F / k``; with the friction on the motor, nothing moves."""
    ts, n = 1e-3, 3000
    force = np.full(n, 40.0)  # below fc = 60 N
    ratio, f_r = 0.5, 30.0
    table, motor = _open_loop(_friction_row(ratio, f_r, 5, 1.0), force, ts, 5)
    mu = 0.5 * 10.0 * 0.5
    k = mu * (2 * np.pi * f_r) ** 2
    # the load's velocity is 0 at the end of every substep; within one, the held friction
    # lets it sway by a fraction of the spring's own motion (1e-4 of it here)
    assert np.max(np.abs(table - table[0])) < 1e-3 * 40.0 / k
    assert abs((motor[-1] - table[-1]) - 40.0 / k) < 1e-3 * 40.0 / k
    table, motor = _open_loop(_friction_row(ratio, f_r, 5, 0.0), force, ts, 5)
    assert np.all(table == table[0]) and np.all(motor == motor[0])


def test_compliance_is_validated() -> None:
    with pytest.raises(ValueError, match=r"compliance_load_fraction=1.2: expected a value in"):
        Axis().with_effects(compliance_load_fraction=1.2)
    with pytest.raises(ValueError, match=r"compliance_frequency=0.0: expected .* Hz"):
        Axis().with_effects(compliance_frequency=0.0)
    with pytest.raises(ValueError, match=r"compliance_damping=-0.1"):
        Axis().with_effects(compliance_damping=-0.1)
    with pytest.raises(ValueError, match=r"compliance_friction='table': expected one of"):
        Axis().with_effects(compliance_friction="table")


def test_unstable_full_closed_loop_is_refused_naming_the_compliance() -> None:
    with pytest.raises(ValueError, match=r"^effects.compliance_load_fraction=0.5 .* feedback "
                                         r"from the table .*although the rigid axis is stable"):
        Axis().with_effects(compliance_load_fraction=0.5, compliance_frequency=20.0,
                            measurement="table")


def test_axis_spec_carries_compliance() -> None:
    spec = Axis().with_effects(compliance_load_fraction=0.3, compliance_frequency=60.0,
                               compliance_damping=0.02).to_dict()
    axis = Axis.from_dict(spec)
    p = axis.pack()
    assert (p[PL.COMP_RATIO], p[PL.COMP_FREQ], p[PL.COMP_ZETA]) == (0.3, 60.0, 0.02)
    assert p[PL.COMP_LOAD] == 0.0
    on_load = Axis.from_dict(Axis().with_effects(
        compliance_load_fraction=0.3, compliance_friction="load").to_dict())
    assert on_load.effects.compliance_friction == "load"
    assert on_load.pack()[PL.COMP_LOAD] == 1.0
    assert on_load.pack()[PL.COMP_B_MOTOR] == 0.0
    split = Axis.from_dict(Axis().with_effects(
        compliance_load_fraction=0.3, compliance_friction="load",
        compliance_damping_motor_share=0.25).to_dict())
    assert split.pack()[PL.COMP_B_MOTOR] == 0.25
    with pytest.raises(ValueError, match="compliance_damping_motor_share"):
        Axis().with_effects(compliance_damping_motor_share=1.5)


def test_rigid_rows_are_padded() -> None:
    old = PL.default_row(3.0)[:PL.N_PLANT_RIGID]
    row = PL.pad_row(old)
    assert row.shape == (PL.N_PLANT,) and row[PL.COMP_RATIO] == 0.0
    before = PL.default_row(3.0)[:PL.N_PLANT_LOAD_FRICTION]
    assert np.array_equal(PL.pad_row(before), PL.default_row(3.0))
    with pytest.raises(ValueError, match=f"expected a plant row of {PL.N_PLANT}"):
        PL.pad_row(np.zeros(5))
