"""Backlash between two bodies (``backlash_load_fraction > 0``): the plant against mechanics
worked out by hand (impacts, coasting, contact forces) and its limits (no gap, a massless
load)."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.axis import plant as PL
from fricbench.trajectories.base import Reference


def _row(mass: float = 2.0, gap: float = 1e-3, share: float = 0.25, fc: float = 0.0,
         damping: float = 0.0, ts: float = 1e-3, n_sub: int = 4) -> np.ndarray:
    p = PL.default_row(mass, damping, ts, n_sub)
    p[PL.BACKLASH] = gap
    p[PL.BL_LOAD] = share
    p[PL.FC] = fc
    return p


def _run(p: np.ndarray, n: int, force: float | np.ndarray, x: float = 0.0, v: float = 0.0,
         d: float = 0.0, dv: float = 0.0) -> np.ndarray:
    """Samples of (motor x, motor v, deflection d, its rate) under a force held per sample."""
    c = PL.constants(p)
    f = np.broadcast_to(np.asarray(force, dtype=float), (n,))
    out = np.empty((n, 4))
    z = theta = 0.0
    x_play = x
    for k in range(n):
        x, v, z, x_play, d, dv, theta, _ = PL.advance(c, x, v, z, x_play, d, dv, theta, f[k])
        out[k] = x, v, d, dv
        assert x_play == x  # two bodies: the table is x + d, no play operator on top
    return out


def test_an_impact_is_inelastic_and_keeps_the_momentum() -> None:
    # no friction, no damping, no force: the motor at 10 mm/s meets the load at rest
    m, share, gap = 2.0, 0.25, 1e-3
    out = _run(_row(m, gap, share), 200, 0.0, v=0.01, dv=-0.01)
    # the motor crosses half the gap alone in 50 ms, then both move at m_M v0 / M
    x, v, d, dv = out[-1]
    assert v == pytest.approx((1 - share) * 0.01, rel=1e-12)
    assert d == pytest.approx(-0.5 * gap, rel=1e-12)
    assert dv == 0.0
    # the centre of mass moved at the initial momentum's speed throughout
    t = 0.2
    x_cm = x + share * d
    assert x_cm == pytest.approx((1 - share) * 0.01 * t, rel=1e-9)


def test_a_load_coasts_against_its_friction_inside_the_gap() -> None:
    # the load moves at 4 mm/s in the middle of a 2 mm gap, the motor at rest: it stops after
    # v^2 m_L / (2 F_c) and the motor feels nothing
    m, share, fc, v0 = 2.0, 0.5, 0.1, 0.004
    out = _run(_row(m, 2e-3, share, fc=fc, n_sub=8), 300, 0.0, dv=v0)
    x, v, d, dv = out[-1]
    assert x == 0.0 and v == 0.0
    assert dv == pytest.approx(-0.0, abs=1e-15)
    assert d == pytest.approx(v0**2 * share * m / (2 * fc), rel=1e-3)


def test_a_contact_pushes_but_never_pulls() -> None:
    # the motor pushes the load (which carries all the friction) forward, then the drive
    # brakes: the load leaves the motor and coasts on until its friction stops it
    m, share, fc, gap = 2.0, 0.5, 0.2, 1e-3
    force = np.r_[np.full(100, 1.0), np.full(400, -1.0)]
    out = _run(_row(m, gap, share, fc=fc), force.size, force, d=-0.5 * gap)
    d = out[:, 2]
    assert np.all(np.abs(d) <= 0.5 * gap)
    assert np.all(d[:100] == -0.5 * gap)  # pushed: in contact on the motor's front
    # braking: the motor (0.8 N more than the load's friction per kg) decelerates faster than
    # the load (0.2 N / 1 kg), so the two part at once
    assert d[101] > -0.5 * gap
    # and the load catches the motor's other face or stops: never beyond the gap
    assert np.max(d) <= 0.5 * gap


def test_a_vanishing_gap_is_the_rigid_axis() -> None:
    rng = np.random.default_rng(3)
    force = rng.normal(0.0, 1.0, 400)
    rigid = _run(_row(gap=0.0, fc=0.3, damping=0.5), 400, force)
    tight = _run(_row(gap=1e-12, share=0.4, fc=0.3, damping=0.5), 400, force)
    np.testing.assert_allclose(tight[:, 0], rigid[:, 0], atol=1e-10)


def test_a_massless_load_is_the_play_operator_in_a_loop() -> None:
    """In the closed loop the load share's limit at 0 is close to the play operator; a heavy
    load differs (the loop meets the motor alone inside the gap)."""
    ts = 1e-3
    t = np.arange(4000) * ts
    x_ref = 2e-3 * np.sin(2 * np.pi * 1.0 * t)
    v_ref = np.gradient(x_ref, ts)
    ref = Reference(t=t, x=x_ref, v=v_ref, a=np.gradient(v_ref, ts))
    axis = Axis().with_effects(backlash=20e-6)
    play = simulate(axis, ref, seed=0).x
    light = simulate(axis.with_effects(backlash_load_fraction=1e-6), ref, seed=0).x
    heavy = simulate(axis.with_effects(backlash_load_fraction=0.6), ref, seed=0).x
    assert np.all(np.isfinite(heavy))
    gap = 20e-6
    # the massless load differs from the play operator only in where the motor's friction
    # goes while it crosses the gap: less than the gap itself
    assert np.max(np.abs(light - play)) < gap
    assert np.sqrt(np.mean((heavy - light) ** 2)) > 0.01 * gap


def test_the_two_masses_of_a_compliant_axis_and_a_two_body_gap_exclude_each_other() -> None:
    with pytest.raises(ValueError, match="backlash_load_fraction=0.3 with compliance_load"):
        Axis().with_effects(backlash=1e-5, backlash_load_fraction=0.3,
                            compliance_load_fraction=0.2)
    with pytest.raises(ValueError, match="backlash_load_fraction"):
        Axis().with_effects(backlash_load_fraction=1.5)


def test_a_row_of_the_previous_layout_is_padded_with_the_play_operator() -> None:
    row37 = PL.default_row(3.0)[:PL.N_PLANT_HEATED]
    row = PL.pad_row(row37)
    assert row.shape == (PL.N_PLANT,)
    assert row[PL.BL_LOAD] == 0.0
