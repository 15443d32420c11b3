"""kalman: the tuning rule gives the wanted bandwidth; the observer cuts the error."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

import fricbench  # noqa: F401
from fricbench.bench.runner import bench_env
from fricbench.compensators import EpisodeContext, feature_index
from fricbench.compensators.kalman import (
    KalmanDisturbanceObserver,
    dob_model,
    initial_covariance,
    observer_poles,
)
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


@pytest.mark.parametrize(("env_id", "trajectory"), [("fricbench/PaperAxis-v0", "s_curve"),
                                                    ("fricbench/CircleContouring-v0", "circle")])
def test_filter_is_filterpys(env_id: str, trajectory: str) -> None:
    """The observer (its gain schedule) against filterpy's KalmanFilter fed the same
    measurements, on a drawn plant with encoder and current noise: the forces agree to 1e-10 of
    the largest (measured: 5.0e-12 on the s-curve, 2.5e-12 on the circle)."""
    kal = KalmanDisturbanceObserver()
    env = bench_env(env_id, kal, seed=5)
    obs, _ = env.reset(seed=5, options={"trajectory": trajectory})
    ctx = env.episode_context()
    kal.reset(ctx, seed=5)
    mdl, cfg, scale = dob_model(ctx.nominal_axis, kal.bandwidth), ctx.task.observation, \
        ctx.task.action_scale
    x_ref, v_ref = np.atleast_2d(ctx.reference.x), np.atleast_2d(ctx.reference.v)
    filters = []
    for i in range(ctx.n_axes):
        kf = KalmanFilter(dim_x=3, dim_z=1, dim_u=1)
        kf.F, kf.B, kf.H, kf.Q, kf.R = mdl["F"], mdl["B"], mdl["H"], mdl["Q"], mdl["R"]
        kf.x = np.array([[x_ref[i, 0]], [v_ref[i, 0]], [0.0]])
        kf.P = initial_covariance(ctx.nominal_axis, mdl)
        filters.append(kf)
    ours, theirs, k = [], [], 0
    while True:
        a = kal.act(obs)
        obs = np.asarray(obs, dtype=np.float64)  # as act reads it (float32 products round)
        ours.append(-kal.d_hat_)
        for i, kf in enumerate(filters):
            if k > 0:
                f = obs[feature_index("motor_force", i, cfg)] * cfg.force_scale
                kf.predict(u=np.array([[f]]))
            e = obs[feature_index("error", i, cfg)] * cfg.error_scale
            kf.update(np.array([[x_ref[i, k] - e]]))
        theirs.append([-kf.x[2, 0] for kf in filters])
        obs, _, _, truncated, _ = env.step(a)
        k += 1
        if truncated:
            break
    ours_f, theirs_f = np.clip(ours, -scale, scale), np.clip(theirs, -scale, scale)
    assert np.max(np.abs(theirs_f)) > 100.0  # friction was observed
    assert np.max(np.abs(ours_f - theirs_f)) <= 1e-10 * np.max(np.abs(theirs_f))
