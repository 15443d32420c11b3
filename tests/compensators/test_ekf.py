"""ekf: analytic Jacobian, the scalar update against filterpy's, the level converging, errors."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

import fricbench  # noqa: F401
from fricbench.compensators import EpisodeContext, make_compensator
from fricbench.compensators.ekf import (
    ExtendedFrictionObserver,
    ekf_model,
    ekf_transition,
    stribeck_shape,
)
from fricbench.friction import make_friction
from fricbench.gym import ServoAxisEnv, get_spec

AXIS = get_spec("fricbench/PaperAxis-v0").axis


@pytest.mark.parametrize("v", [-5e-3, -2e-3, -1.5e-4, -2e-5, 0.0, 3e-5, 8e-5, 1e-3, 2.5e-3, 0.05])
@pytest.mark.parametrize("force", [-400.0, 0.0, 250.0])
def test_jacobian_matches_finite_differences(v: float, force: float) -> None:
    model = ekf_model(AXIS, residual_time=0.05)
    state = np.array([1.0e-3, v, 330.0, 12.0])
    jac = np.diag([1.0, 1.0, 1.0, model.decay])  # the constant rows, as the filter fills them
    ekf_transition(state, force, model, jac)
    # central differences, step relative to each component's scale
    steps = np.array([1e-9, max(1e-9, 1e-4 * model.eps), 1e-3, 1e-3])
    fd = np.zeros((4, 4))
    for j in range(4):
        dp, dm = state.copy(), state.copy()
        dp[j] += steps[j]
        dm[j] -= steps[j]
        fd[:, j] = (ekf_transition(dp, force, model) - ekf_transition(dm, force, model))[:, 0] \
            / (2 * steps[j])
    assert np.allclose(jac, fd, rtol=1e-4, atol=1e-9), (jac, fd)


def test_shape_derivatives_match_finite_differences() -> None:
    model = ekf_model(AXIS)
    for v in (-3e-3, -1e-4, 1e-5, 6e-4, 2e-3):
        h = 1e-4 * min(abs(v), model.eps)
        s, s1, s2 = stribeck_shape(v, model)
        sp, s1p, _ = stribeck_shape(v + h, model)
        sm, s1m, _ = stribeck_shape(v - h, model)
        assert s1 == pytest.approx((sp - sm) / (2 * h), rel=1e-5)
        assert s2 == pytest.approx((s1p - s1m) / (2 * h), rel=1e-5, abs=1e-3)


def test_shape_is_the_stribeck_law_while_sliding() -> None:
    model = ekf_model(AXIS)
    fc, fs, vs = 350.0, 500.0, 2e-3
    for v in (1e-3, 2e-3, 5e-3, -3e-3):
        law = np.sign(v) * (fc + (fs - fc) * np.exp(-(v / vs) ** 2))
        assert fc * stribeck_shape(v, model)[0] == pytest.approx(law, rel=1e-6)


def test_position_update_matches_filterpy() -> None:
    """The scalar update gives filterpy's ``ExtendedKalmanFilter.update`` to round-off."""
    comp = ExtendedFrictionObserver()
    env = ServoAxisEnv(axis=AXIS, task=get_spec("fricbench/PaperAxis-v0").task)
    env.reset(seed=0, options={"trajectory": "s_curve"})
    comp.reset(env.episode_context(), seed=0)
    kf = comp._filters[0]
    rng = np.random.default_rng(5)
    a = rng.normal(size=(4, 4)) * np.array([1e-7, 1e-4, 10.0, 10.0])
    kf.P = a @ a.T + np.diag([1e-14, 1e-8, 100.0, 100.0])
    kf.x = np.array([[1e-3], [2e-3], [340.0], [5.0]])
    ref = ExtendedKalmanFilter(dim_x=4, dim_z=1)
    ref.x, ref.P, ref.R = kf.x.copy(), kf.P.copy(), kf.R.copy()
    z = 1.0e-3 + 3e-7
    kf.update_position(z)
    ref.update(np.array([[z]]), lambda x: np.array([[1.0, 0.0, 0.0, 0.0]]), lambda x: x[:1])
    assert np.allclose(kf.x, ref.x, rtol=1e-10, atol=0.0)
    assert np.allclose(kf.P, ref.P, rtol=1e-8, atol=1e-12 * np.abs(ref.P).max())


def _level_run(fc: float, gain: float) -> tuple[float, float]:
    """Estimated level after an s_curve (out and back at 50 mm/s) on a plant of level ``fc``
    (same F_s / F_c as the nominal 350/500 N the filter is told), no noise; and max |e|."""
    spec = get_spec("fricbench/PaperAxis-v0")
    plant = replace(AXIS, friction=make_friction("stribeck", fc=fc, fs=fc * 500.0 / 350.0,
                                                 vs=2e-3))
    env = ServoAxisEnv(axis=AXIS, task=spec.task, plant=plant)
    obs, _ = env.reset(seed=0, options={"trajectory": "s_curve"})
    comp = ExtendedFrictionObserver(gain=gain)
    comp.reset(env.episode_context(), seed=0)
    worst = 0.0
    while True:
        obs, _, _, truncated, info = env.step(comp.act(obs))
        worst = max(worst, abs(float(info["error_m"][0])))
        if truncated:
            return comp.level_[0], worst


@pytest.mark.parametrize("fc", [280.0, 420.0])
def test_level_converges_to_the_plant(fc: float) -> None:
    """Told 350 N, the plant has 280 or 420 N (-20 % / +20 %): the estimate ends within 3 %."""
    level, _ = _level_run(fc, gain=0.0)  # observe only
    assert level == pytest.approx(fc, rel=0.03)


def test_feedback_cuts_the_error() -> None:
    _, worst_none = _level_run(420.0, gain=0.0)
    level, worst = _level_run(420.0, gain=1.0)
    assert worst < 0.6 * worst_none
    assert level == pytest.approx(420.0, rel=0.1)


def test_same_seed_same_actions() -> None:
    runs = []
    for _ in range(2):
        comp = make_compensator("ekf")
        env = ServoAxisEnv(axis=AXIS, task=get_spec("fricbench/PaperAxis-v0").task)
        obs, _ = env.reset(seed=3, options={"trajectory": "s_curve"})
        comp.reset(EpisodeContext(env.reference, env.axis, env.task), seed=3)
        acts = []
        for _ in range(1500):
            a = comp.act(obs)
            acts.append(a)
            obs, *_ = env.step(a)
        runs.append(np.array(acts))
    assert np.array_equal(runs[0], runs[1])


@pytest.mark.parametrize(("name", "value"), [
    ("residual_bandwidth", 0.0), ("level_std", -0.1), ("level_time", 0.0), ("eps", 0.0),
    ("gain", -1.0), ("max_force", 0.0), ("residual_bandwidth", float("nan")),
])
def test_bad_arguments_name_the_parameter(name: str, value: float) -> None:
    with pytest.raises(ValueError, match=name):
        ExtendedFrictionObserver(**{name: value})


def test_wrong_type_raises_type_error() -> None:
    with pytest.raises(TypeError, match="eps"):
        ExtendedFrictionObserver(eps="small")  # type: ignore[arg-type]
