"""The vector env's step with the plant constants unpacked once per step gives, bit for bit, what
the per-row path (the step as it was before, unpacking every row) gives; and each sub-env's
rollout is, bit for bit, that of a scalar env given the same actions."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from fricbench.axis.params import Effects
from fricbench.gym import ServoAxisEnv, get_spec
from fricbench.gym.task import Randomization, TaskConfig, TrajectoryChoice
from fricbench.gym.vector import ServoAxisVectorEnv


def _rollout(venv: ServoAxisVectorEnv, steps: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed + 100)
    obs, _ = venv.reset(seed=seed)
    out = [obs]
    for t in range(steps):
        # out-of-range actions too (clipping), float32 and float64 alternately
        a = rng.uniform(-1.5, 1.5, (venv.num_envs, 1))
        o, r, term, trunc, _ = venv.step(a.astype(np.float32) if t % 2 else a)
        out += [o, r, term, trunc]
    return out + [venv._batch.S.copy()]


def _effects_axis():  # type: ignore[no-untyped-def]
    axis = get_spec("fricbench/PaperAxis-v0").axis.with_controller(kv=150.0)
    return replace(axis, effects=Effects(
        backlash=2e-6, cogging_amplitude=20.0, friction_gradient=0.5, coulomb_asymmetry=30.0,
        viscous_asymmetry=20.0, friction_variation=0.1, thermal_drift=5e-6,
        thermal_time_constant=0.5, quantization=1e-7, noise_std=2e-7, delay_samples=1,
        compliance_load_fraction=0.3, compliance_frequency=120.0, compliance_damping=0.2))


@pytest.mark.parametrize("env_id", ["fricbench/PaperAxis-v0", "fricbench/LuGreAxis-v0",
                                    "fricbench/EMPS-v0", "effects"])
@pytest.mark.parametrize("n", [1, 7, 300])
def test_shared_plant_step_is_bit_identical_to_the_per_row_step(env_id: str, n: int) -> None:
    spec = get_spec("fricbench/PaperAxis-v0" if env_id == "effects" else env_id)
    axis = _effects_axis() if env_id == "effects" else spec.axis
    task = replace(spec.task, action="offset", action_scale=1e-5) if env_id == "effects" \
        else spec.task
    fast = ServoAxisVectorEnv(num_envs=n, axis=axis, task=task, reference_pool=2, seed=n)
    slow = ServoAxisVectorEnv(num_envs=n, axis=axis, task=task, reference_pool=2, seed=n)
    assert fast._shared_plant
    slow._batch.uniform = False  # the per-row path: every sub-env unpacks its own plant row
    a, b = _rollout(fast, 300, n), _rollout(slow, 300, n)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.dtype == y.dtype and np.array_equal(x, y)
    # the motor force moved over the rollout (not a trivially equal standstill)
    assert np.ptp(np.stack(a[1:-1:4])[:, :, 6]) > 0.0


def test_randomized_env_unpacks_each_row() -> None:
    venv = ServoAxisVectorEnv(num_envs=3, axis=get_spec("fricbench/RandomFriction-v0").axis,
                              task=get_spec("fricbench/RandomFriction-v0").task)
    venv.reset(seed=0)
    assert not venv._shared_plant


def test_a_plant_set_per_row_is_stepped_per_row() -> None:
    """Rows given their own plants through ``set_params`` (a per-episode plant draw without
    friction randomisation) step as sub-envs of their own, not as copies of row 0."""
    spec = get_spec("fricbench/PaperAxis-v0")
    mixed = ServoAxisVectorEnv(num_envs=2, axis=spec.axis, task=spec.task, reference_pool=1,
                               seed=3)
    heavy = replace(spec.axis, mechanics=replace(spec.axis.mechanics,
                                                 mass=2.0 * spec.axis.mechanics.mass))
    mixed._batch.set_params(1, heavy)
    assert not mixed._shared_plant
    alone = ServoAxisVectorEnv(num_envs=2, axis=heavy, task=spec.task, reference_pool=1,
                               seed=3)
    a, b = _rollout(mixed, 200, 2), _rollout(alone, 200, 2)
    # row 1 of the mixed batch is the heavy axis: as in a batch of heavy axes only
    for x, y in zip(a, b, strict=True):
        if x.ndim >= 1 and x.shape[0] == 2:
            assert np.array_equal(x[1], y[1])
    # and row 0 is not (the light axis moves differently)
    assert any(x.ndim >= 1 and x.shape[0] == 2 and not np.array_equal(x[0], y[0])
               for x, y in zip(a, b, strict=True))


def _scalar_case(case: str) -> tuple[Any, TaskConfig]:
    """The axis and task of ``case`` on a short fixed reference, friction not redrawn."""
    spec = get_spec("fricbench/PaperAxis-v0" if case == "effects" else case)
    axis, task = spec.axis, spec.task
    if case == "effects":
        # every effect but the measurement noise: the scalar envs draw theirs from generators
        # of their own, the vector env from one for all sub-envs
        axis = replace(_effects_axis(), effects=replace(_effects_axis().effects, noise_std=0.0))
        task = replace(task, action="offset", action_scale=1e-5)
    duration = 60 * axis.controller.ts
    return axis, replace(task, randomize=Randomization(), trajectories=(
        TrajectoryChoice("random", {"duration": duration, "seed": 7}),))


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("case", ["fricbench/PaperAxis-v0", "fricbench/LuGreAxis-v0",
                                  "fricbench/EMPS-v0", "fricbench/DCMotor-v0",
                                  "fricbench/RandomFriction-v0", "effects"])
def test_vector_rollout_equals_the_scalar_envs_bit_for_bit(case: str, mode: str) -> None:
    """Sub-env ``i`` of the vector env and a scalar env given the same actions give the same
    observations, truncations and final observations, bit for bit, and the same rewards to
    rounding, over three episodes and the autoresets between them (Gymnasium's next-step and
    same-step modes)."""
    axis, task = _scalar_case(case)
    n = 4
    venv = ServoAxisVectorEnv(num_envs=n, axis=axis, task=task, reference_pool=1, seed=0,
                              autoreset_mode=mode)
    envs = [ServoAxisEnv(axis=axis, task=task) for _ in range(n)]
    vobs, _ = venv.reset(seed=1)
    sobs = np.stack([env.reset(seed=i)[0] for i, env in enumerate(envs)])
    assert vobs.dtype == sobs.dtype == np.float32 and np.array_equal(vobs, sobs)
    rng = np.random.default_rng(2)
    pending = np.zeros(n, dtype=bool)  # next-step mode: the scalar env resets on this step
    truncations, apart = 0, False
    for t in range(3 * 61):
        # out-of-range actions too (clipping), float32 and float64 alternately
        a = rng.uniform(-1.5, 1.5, (n, 1))
        a = a.astype(np.float32) if t % 2 else a
        vobs, vrew, vterm, vtrunc, vinfo = venv.step(a)
        for i, env in enumerate(envs):
            if pending[i]:
                sobs[i] = env.reset()[0]
                rew, trunc = 0.0, False
                pending[i] = False
            else:
                sobs[i], r, term, trunc, _ = env.step(a[i])
                rew = float(r)
                assert not term
                if trunc and mode == "SameStep":
                    assert np.array_equal(vinfo["final_obs"][i], sobs[i])
                    sobs[i] = env.reset()[0]
                elif trunc:
                    pending[i] = True
            # the reward to rounding, not bit for bit: the scalar env scores
            # -(e e_s / r_s)^2 - w a^2 in Python, the compiled step in the order of
            # step_reward (as since the fused step was written; making it the scalar env's
            # would move the rewards PPO trains the rl compensators on)
            np.testing.assert_allclose(vrew[i], rew, rtol=1e-14, atol=0.0)
            assert vtrunc[i] == trunc and not vterm[i]
            truncations += int(trunc)
        assert np.array_equal(vobs, sobs), f"step {t}"
        apart = apart or len({row.tobytes() for row in vobs}) == n
    assert truncations >= 2 * n
    # the sub-envs moved apart (different actions): not one trajectory compared four times
    assert apart


def test_reward_is_the_written_out_order_bit_for_bit() -> None:
    """The vector env's reward is, bit for bit, ``r = -e^2 - (a^2) w`` rounded once, with
    ``e = ((1 / e_s) e_s) d (1 / r_s)`` rounded at each product (:func:`step_reward`: the order
    its fast-math compile had chosen, now fixed), computed here exactly with fractions from the
    env's own error ``d = x_ref - x_meas`` and clipped action ``a``."""
    from fractions import Fraction

    from fricbench.axis.kernel import S_XMEAS

    spec = get_spec("fricbench/PaperAxis-v0")
    task = replace(spec.task, trajectories=(TrajectoryChoice("random", {"duration": 0.05}),))
    n = 5
    venv = ServoAxisVectorEnv(num_envs=n, axis=spec.axis, task=task, reference_pool=2, seed=1)
    venv.reset(seed=2)
    e_s, r_s = venv._scales[0], task.reward.error_scale
    w = task.reward.action_weight
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(120):
        a = rng.uniform(-1.5, 1.5, (n, 1))
        held = venv._autoreset.copy()
        _, reward, _, _, _ = venv.step(a)
        d = venv._X[venv._ref_id, venv._k] - venv._batch.S[:, S_XMEAS]
        for i in np.flatnonzero(~held):
            ai = min(1.0, max(-1.0, float(a[i, 0])))
            e = (((1.0 / e_s) * e_s) * float(d[i])) * (1.0 / r_s)
            exact = float(-Fraction(e) * Fraction(e) - Fraction((ai * ai) * w))
            assert reward[i] == exact and np.signbit(reward[i]) == np.signbit(exact)
            checked += 1
    assert checked > 500
