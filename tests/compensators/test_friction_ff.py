"""friction-ff: the Stribeck fit recovers the simulated friction; the feedforward is sane."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.axis import simulate
from fricbench.compensators.friction_ff import FrictionFeedforward, fit_stribeck
from fricbench.compensators.training_data import env_setup, training_references


def test_fit_recovers_stribeck_parameters() -> None:
    axis, _ = env_setup("fricbench/PaperAxis-v0")
    refs = training_references(2, seed=5, duration=15.0)
    runs = [simulate(axis, r, seed=i) for i, r in enumerate(refs)]
    fit = fit_stribeck(np.array([r.u for r in runs]), np.array([r.x for r in runs]), 1e-3)
    fr = axis.friction
    assert fit.fc == pytest.approx(fr.fc, rel=0.03)
    assert fit.fs == pytest.approx(fr.fs, rel=0.05)
    assert fit.vs == pytest.approx(fr.vs, rel=0.15)
    assert fit.mass == pytest.approx(axis.mechanics.mass, rel=0.05)


def test_fit_without_motion_raises() -> None:
    with pytest.raises(ValueError, match="too little motion"):
        fit_stribeck(np.zeros(2000), np.zeros(2000), 1e-3)


def test_feedforward_is_odd_and_ramped() -> None:
    comp = FrictionFeedforward(n_runs=1, run_duration=6.0, v_eps=1e-4, advance=0)
    comp.fit("fricbench/PaperAxis-v0", seed=0)
    v = np.linspace(-0.01, 0.01, 2001)
    u = comp.force(v)
    assert np.allclose(u, -u[::-1], atol=1e-9)
    assert u[1000] == 0.0
    assert abs(comp.force(np.array([5e-5]))[0]) < 0.6 * comp.model_.fs
    assert comp.force(np.array([0.01]))[0] == pytest.approx(comp.model_.fc, rel=0.05)


def test_constructor_validates() -> None:
    with pytest.raises(ValueError, match="v_eps"):
        FrictionFeedforward(v_eps=-1.0)
    with pytest.raises(TypeError, match="n_runs"):
        FrictionFeedforward(n_runs=1.5)  # type: ignore[arg-type]


def test_pick_smoothing_breaks_a_tie_of_maxima_by_the_rms() -> None:
    """Mean maxima within the sensor's step are a tie, decided by the RMS error: one
    run's maximum moving by one encoder step must not flip the choice."""
    from fricbench.compensators.friction_ff import pick_smoothing

    q = 0.25e-6
    grid = [(14.2544e-6, 1.90e-6, 2e-4, 2), (14.2545e-6, 1.70e-6, 2.5e-5, 2),
            (14.3169e-6, 1.60e-6, 5e-5, 1), (20.0e-6, 0.5e-6, 1e-3, 0)]
    assert pick_smoothing(grid, q)[2] == 5e-5  # within one step of the lowest: lowest RMS
    bumped = [(g[0] + (q / 4 if g[2] == 2e-4 else 0.0),) + g[1:] for g in grid]
    assert pick_smoothing(bumped, q)[2] == pick_smoothing(grid, q)[2]
    # a finer sensor: only the 0.1 % tie is left
    assert pick_smoothing(grid, 1e-9)[2] == 2.5e-5
    # a clear winner on the maxima wins whatever its RMS
    assert pick_smoothing([(10e-6, 3e-6, 1e-4, 0), (12e-6, 1e-6, 1e-3, 0)], q)[2] == 1e-4
    with pytest.raises(ValueError, match="grid"):
        pick_smoothing([], q)
