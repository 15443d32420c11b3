"""kalman: the tuning rule gives the wanted bandwidth; the observer cuts the error."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import fricbench  # noqa: F401
from fricbench.compensators import EpisodeContext
from fricbench.compensators.kalman import KalmanDisturbanceObserver, dob_model, observer_poles
from fricbench.gym import get_spec


@pytest.mark.parametrize("bandwidth", [100.0, 1000.0])
def test_poles_on_butterworth_circle(bandwidth: float) -> None:
    axis = get_spec("fricbench/PaperAxis-v0").axis
    poles = observer_poles(axis, bandwidth)
    assert np.allclose(np.abs(poles), bandwidth, rtol=0.05)


def test_measurement_variance_from_encoder_step() -> None:
    axis = get_spec("fricbench/PaperAxis-v0").axis
    r = dob_model(axis, 500.0)["R"][0, 0]
    assert r == pytest.approx(axis.effects.quantization**2 / 12)


def _max_error(comp: KalmanDisturbanceObserver | None, traj: str) -> float:
    env = gym.make("fricbench/PaperAxis-v0")
    obs, _ = env.reset(seed=0, options={"trajectory": traj})
    u = env.unwrapped
    if comp is not None:
        comp.reset(EpisodeContext(u.reference, u.axis, u.task), seed=0)
    worst = 0.0
    while True:
        a = comp.act(obs) if comp is not None else np.zeros(1, np.float32)
        obs, _, _, truncated, info = env.step(a)
        worst = max(worst, abs(float(info["error_m"][0])))
        if truncated:
            return worst


def test_observer_cuts_error_on_s_curve() -> None:
    assert _max_error(KalmanDisturbanceObserver(), "s_curve") < 0.6 * _max_error(None, "s_curve")


def test_estimate_matches_friction_while_sliding() -> None:
    comp = KalmanDisturbanceObserver(bandwidth=300.0, gain=0.0)  # observe only
    env = gym.make("fricbench/PaperAxis-v0")
    obs, _ = env.reset(seed=0, options={"trajectory": "s_curve"})
    u = env.unwrapped
    comp.reset(EpisodeContext(u.reference, u.axis, u.task), seed=0)
    v_ref = u.reference.v
    k = int(np.argmax(v_ref))  # cruising at full feed
    for _ in range(k):
        obs, *_ = env.step(comp.act(obs))
    d_hat = float(comp.d_hat_[0])
    assert d_hat == pytest.approx(-u.axis.friction.fc, rel=0.1)


def test_validation() -> None:
    with pytest.raises(ValueError, match="bandwidth"):
        KalmanDisturbanceObserver(bandwidth=0.0)
