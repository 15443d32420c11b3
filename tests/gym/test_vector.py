"""The native vector env's fused step: autoreset, bad actions, clipping, divergence."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from fricbench.axis import SimulationDivergedError
from fricbench.axis import kernel as K
from fricbench.gym import get_spec
from fricbench.gym.task import TrajectoryChoice
from fricbench.gym.vector import ServoAxisVectorEnv


def _venv(n: int = 3, trajectory: str = "s_curve", **axis_changes: float) -> ServoAxisVectorEnv:
    spec = get_spec("fricbench/PaperAxis-v0")
    task = replace(spec.task, trajectories=(TrajectoryChoice(trajectory),))
    axis = spec.axis.with_controller(**axis_changes) if axis_changes else spec.axis
    return ServoAxisVectorEnv(num_envs=n, axis=axis, task=task, reference_pool=1)


def test_next_step_autoreset_holds_the_reset_row() -> None:
    venv = _venv(2)
    first, _ = venv.reset(seed=3)
    length = int(venv._len[0])
    zeros = np.zeros((2, 1), dtype=np.float32)
    for step in range(1, length):
        obs, rew, term, trunc, _ = venv.step(zeros)
        assert not term.any()
        assert trunc.all() == (step == length - 1)
    assert trunc.all()
    # NEXT_STEP: the step after truncation returns the reset observation, reward 0, and does
    # not move the axis; the one after that moves again
    obs, rew, _, trunc, _ = venv.step(np.ones((2, 1), dtype=np.float32))
    np.testing.assert_allclose(obs, first, atol=1e-6)
    assert (rew == 0.0).all() and not trunc.any()
    assert (obs[:, 5] == 0.0).all()  # previous action of a reset row is 0
    assert (venv._k == 0).all()
    obs, rew, _, _, _ = venv.step(np.ones((2, 1), dtype=np.float32))
    assert (venv._k == 1).all() and (rew < 0.0).all()


def test_nan_action_raises_and_changes_nothing() -> None:
    venv = _venv(3)
    venv.reset(seed=0)
    for _ in range(20):
        venv.step(np.full((3, 1), 0.1, dtype=np.float32))
    state, k = venv._batch.S.copy(), venv._k.copy()
    bad = np.full((3, 1), 0.1)
    bad[2, 0] = np.nan
    with pytest.raises(ValueError, match=r"actions\[2\].*NaN or inf"):
        venv.step(bad)
    bad[2, 0] = -np.inf
    with pytest.raises(ValueError, match="NaN or inf"):
        venv.step(bad)
    np.testing.assert_array_equal(venv._batch.S, state)
    np.testing.assert_array_equal(venv._k, k)
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros((4, 1)))


def test_out_of_range_actions_are_clipped() -> None:
    a, b = _venv(2), _venv(2)
    a.reset(seed=1)
    b.reset(seed=1)
    for _ in range(30):
        oa, ra, *_ = a.step(np.full((2, 1), 7.0))
        ob, rb, *_ = b.step(np.full((2, 1), 1.0))
    np.testing.assert_array_equal(oa, ob)
    np.testing.assert_array_equal(ra, rb)
    assert (oa[:, 5] == 1.0).all()


def test_unstable_parameters_raise_naming_the_sub_env() -> None:
    # such an Axis is refused when built; the runtime check sees gains packed by hand
    venv = _venv(2)
    venv.reset(seed=0)
    venv._batch.P[:, K.P_KV] = 5000.0
    venv._batch.P[:, K.P_IMAX] = 1e9
    with pytest.raises(SimulationDivergedError, match="sub-env 0.*unstable"):
        for _ in range(3000):
            venv.step(np.zeros((2, 1)))


def test_observations_are_fresh_arrays() -> None:
    venv = _venv(2)
    o1, _ = venv.reset(seed=0)
    o2, *_ = venv.step(np.zeros((2, 1)))
    o3, *_ = venv.step(np.zeros((2, 1)))
    assert o2.dtype == np.float32 and o2 is not o3
    assert not np.shares_memory(o2, o3)


def test_step_before_reset_is_refused() -> None:
    venv = _venv(4)
    with pytest.raises(RuntimeError, match=r"reset\(\) before step\(\)"):
        venv.step(np.zeros((4, 1)))


@pytest.mark.parametrize("actions,error,message", [
    (np.zeros((2, 2)), ValueError,
     r"actions has shape \(2, 2\): expected shape \(4, 1\) or \(4,\)"),
    (np.zeros((4, 1, 1)), ValueError, r"shape \(4, 1, 1\)"),
    (np.full((4, 1), "0.5"), TypeError, r"actions has dtype <U3"),
    (np.zeros((4, 1), dtype=complex), TypeError, r"actions has dtype complex128"),
    ("0.5", TypeError, r"actions='0.5' \(str\)"),
])
def test_actions_of_the_wrong_shape_or_kind_are_refused(actions, error, message) -> None:
    venv = _venv(4)
    venv.reset(seed=0)
    state, k = venv._batch.S.copy(), venv._k.copy()
    with pytest.raises(error, match=message):
        venv.step(actions)
    np.testing.assert_array_equal(venv._batch.S, state)
    np.testing.assert_array_equal(venv._k, k)


def test_flat_and_list_actions_step_as_the_action_space_shape() -> None:
    venvs = [_venv(3) for _ in range(3)]
    for v in venvs:
        v.reset(seed=2)
    for _ in range(5):
        out = [venvs[0].step(np.full((3, 1), 0.3, dtype=np.float32)),
               venvs[1].step(np.full(3, 0.3, dtype=np.float32)),
               venvs[2].step([[0.3]] * 3)]
    # the list is float64: same clipped action, same float32 value of 0.3 only up to rounding
    np.testing.assert_array_equal(out[0][0], out[1][0])
    np.testing.assert_allclose(out[0][0], out[2][0], rtol=1e-6, atol=1e-6)


def test_bad_reset_and_constructor_arguments_are_refused() -> None:
    venv = _venv(2)
    with pytest.raises(TypeError, match=r"options=\['x'\] \(list\)"):
        venv.reset(options=["x"])
    with pytest.raises(TypeError, match="seed='x': expected an integer"):
        venv.reset(seed="x")  # type: ignore[arg-type]
    spec = get_spec("fricbench/PaperAxis-v0")
    with pytest.raises(TypeError, match="num_envs=True"):
        ServoAxisVectorEnv(num_envs=True, axis=spec.axis, task=spec.task)
    with pytest.raises(TypeError, match="axis='stribeck': expected an Axis"):
        ServoAxisVectorEnv(num_envs=2, axis="stribeck", task=spec.task)  # type: ignore[arg-type]


def test_same_step_autoreset_matches_next_step_without_the_held_step() -> None:
    # friction redrawn per episode and seeded references: the draws must come in the same order
    spec = get_spec("fricbench/RandomFriction-v0")
    task = replace(spec.task, trajectories=(TrajectoryChoice("random", {"duration": 0.05}),))
    same = ServoAxisVectorEnv(num_envs=3, axis=spec.axis, task=task, autoreset_mode="SameStep")
    nxt = ServoAxisVectorEnv(num_envs=3, axis=spec.axis, task=task)
    assert same.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert nxt.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    o_same, _ = same.reset(seed=5)
    o_next, _ = nxt.reset(seed=5)
    rng = np.random.default_rng(0)
    finished = 0
    for _ in range(160):
        act = rng.uniform(-1.0, 1.0, (3, 1)).astype(np.float32)
        o_same, r_same, _, t_same, info = same.step(act)
        o_next, r_next, _, t_next, _ = nxt.step(act)
        np.testing.assert_array_equal(r_same, r_next)
        np.testing.assert_array_equal(t_same, t_next)
        if t_same.any():
            finished += 1
            np.testing.assert_array_equal(info["_final_obs"], t_same)
            np.testing.assert_array_equal(np.stack(info["final_obs"][t_same]), o_next[t_same])
            assert all(o is None for o in info["final_obs"][~t_same])
            o_next, r_next, _, _, _ = nxt.step(act)  # NEXT_STEP's held step
            assert (r_next[t_same] == 0.0).all()
        else:
            assert info == {}
        np.testing.assert_array_equal(o_same, o_next)
    assert finished >= 2


def test_unknown_autoreset_mode_is_refused() -> None:
    spec = get_spec("fricbench/PaperAxis-v0")
    with pytest.raises(ValueError, match="autoreset_mode='Disabled'"):
        ServoAxisVectorEnv(num_envs=2, axis=spec.axis, task=spec.task, autoreset_mode="Disabled")


def test_the_step_copies_the_features_fill_observation_computes() -> None:
    """The step's reference features come from the env's float32 table (the current sample's
    position, velocity and acceleration and the preview's velocities and accelerations); each
    observation it returns is, bit for bit, what ``fill_observation`` (the reset's and the
    scalar env's path) computes from the env's state, with its preview past the reference's end
    where the table is padded."""
    from fricbench.gym.task import fill_observation

    venv = _venv(5, "random")
    venv.reset(seed=4)
    assert venv._F.dtype == np.float32
    table = venv._F.reshape(venv._X.shape + (3,))
    for col, ref, scale in ((0, venv._X, 1), (1, venv._V, 2), (2, venv._A, 3)):
        assert np.array_equal(table[..., col], (ref * venv._inv_scales[scale]).astype(np.float32))
    rng = np.random.default_rng(5)
    end = int(venv._len.min()) - 1
    for _ in range(end):
        obs, *_ = venv.step(rng.uniform(-1.0, 1.0, (5, 1)))
        expected = np.empty((5, venv._nf))
        fill_observation(venv._batch.S, venv._batch.P, venv._X, venv._V, venv._A, venv._ref_id,
                         venv._k, venv._offsets, venv._prev_action, venv._scales, expected)
        assert np.array_equal(obs, expected.astype(np.float32))
    # the last samples' preview reads the padding beyond the reference
    assert int(venv._k.max()) + int(venv._offsets[-1]) >= int(venv._len.min())
