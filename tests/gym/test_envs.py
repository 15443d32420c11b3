"""Every registered env: both checkers, determinism, bad actions, vector env, rendering."""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import fricbench
from fricbench.axis import SimulationDivergedError
from fricbench.axis import kernel as K
from fricbench.gym import ServoAxisEnv, env_registry, get_spec, register_envs

ALL = env_registry.ids()  # the registry sweep: every env id, plug-ins' too
SINGLE = [e for e in ALL if get_spec(e).task.trajectories[0].id != "circle"]


def test_required_envs_registered() -> None:
    for eid in ("fricbench/PaperAxis-v0", "fricbench/LuGreAxis-v0",
                "fricbench/RandomFriction-v0", "fricbench/CircleContouring-v0"):
        assert eid in ALL
    assert get_spec("fricbench/PaperAxis-v0").axis.friction.id == "stribeck"
    assert get_spec("fricbench/LuGreAxis-v0").axis.friction.id == "lugre"
    assert get_spec("fricbench/RandomFriction-v0").task.randomize.ranges


@pytest.mark.parametrize("env_id", ALL)
def test_passes_both_checkers(env_id: str) -> None:
    env = gym.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env.unwrapped)
        sb3_check_env(env.unwrapped)
    env.close()


@pytest.mark.parametrize("env_id", ALL)
def test_determinism(env_id: str) -> None:
    def rollout() -> tuple[np.ndarray, np.ndarray]:
        env = gym.make(env_id)
        obs, _ = env.reset(seed=42)
        rng = np.random.default_rng(0)
        out, rew = [obs], []
        for _ in range(300):
            obs, r, term, trunc, _ = env.step(rng.uniform(-1, 1, env.action_space.shape))
            out.append(obs)
            rew.append(r)
        return np.array(out), np.array(rew)

    a, ra = rollout()
    b, rb = rollout()
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ra, rb)


def test_randomised_friction_differs_between_episodes() -> None:
    env = gym.make("fricbench/RandomFriction-v0")
    _, i1 = env.reset(seed=1)
    _, i2 = env.reset(seed=2)
    assert i1["friction"] != i2["friction"]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_action_raises(bad: float) -> None:
    env = gym.make("fricbench/PaperAxis-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(np.array([bad], dtype=np.float32))


def test_out_of_range_action_is_clipped() -> None:
    a = gym.make("fricbench/PaperAxis-v0")
    b = gym.make("fricbench/PaperAxis-v0")
    a.reset(seed=0, options={"trajectory": "s_curve"})
    b.reset(seed=0, options={"trajectory": "s_curve"})
    oa = a.step(np.array([5.0], dtype=np.float32))[0]
    ob = b.step(np.array([1.0], dtype=np.float32))[0]
    np.testing.assert_array_equal(oa, ob)


def test_wrong_action_shape_raises() -> None:
    env = gym.make("fricbench/PaperAxis-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3))


@pytest.mark.parametrize("action,error,message", [
    ("0.5", TypeError, r"action='0.5' \(str\): expected real numbers"),
    (np.array(["0.5"]), TypeError, r"action has dtype <U3 \(ndarray\)"),
    (np.array([0.5 + 0.5j]), TypeError, r"action has dtype complex128"),
    ([True], TypeError, r"action has dtype bool \(list\)"),
    (np.zeros((1, 1, 1)), ValueError, r"action has shape \(1, 1, 1\): expected shape \(1,\)"),
    ([[0.1], [0.2, 0.3]], ValueError, r"not a rectangular array"),
])
def test_action_of_the_wrong_kind_is_refused(action, error, message) -> None:
    env = gym.make("fricbench/PaperAxis-v0")
    env.reset(seed=0)
    state = env.unwrapped._batch.S.copy()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a complex action used to warn and run
        with pytest.raises(error, match=message):
            env.step(action)
    np.testing.assert_array_equal(env.unwrapped._batch.S, state)
    assert env.unwrapped._k == 0


@pytest.mark.parametrize("action", [np.array([0.25]), [0.25], 0.25, np.float32(0.25),
                                    np.array([0.25], dtype=np.float16)])
def test_every_accepted_action_form_gives_the_same_step(action) -> None:
    env = gym.make("fricbench/PaperAxis-v0")
    ref = gym.make("fricbench/PaperAxis-v0")
    env.reset(seed=0, options={"trajectory": "s_curve"})
    ref.reset(seed=0, options={"trajectory": "s_curve"})
    for _ in range(3):
        np.testing.assert_array_equal(env.step(action)[0],
                                      ref.step(np.array([0.25], dtype=np.float32))[0])


def test_reset_options_must_be_a_dict() -> None:
    env = gym.make("fricbench/PaperAxis-v0")
    with pytest.raises(TypeError, match=r"options=\['trajectory'\] \(list\): expected a dict"):
        env.reset(options=["trajectory"])


@pytest.mark.parametrize("make", ["make", "make_vec"])
@pytest.mark.parametrize("name", ["axis", "task"])
def test_make_refuses_none_for_the_spec_axis_or_task(make: str, name: str) -> None:
    """``axis=None`` used to give the default Stribeck axis instead of the spec's LuGre."""
    kwargs = {"vectorization_mode": "vector_entry_point"} if make == "make_vec" else {}
    with pytest.raises(TypeError, match=f"{name}=None \\(NoneType\\): expected an? "):
        getattr(gym, make)("fricbench/LuGreAxis-v0", **kwargs, **{name: None})


def test_episode_truncates_at_trajectory_end_and_info_terms() -> None:
    env = gym.make("fricbench/PaperAxis-v0")
    _, info = env.reset(seed=0, options={"trajectory": "s_curve"})
    assert info["trajectory"] == "s_curve"
    n = env.unwrapped.reference.n_samples
    for k in range(n - 1):
        obs, r, term, trunc, info = env.step(np.zeros(1))
        assert not term
        assert trunc == (k == n - 2)
    assert {"error_m", "measured_error_m", "reward_error", "reward_action"} <= set(info)
    assert r == pytest.approx(info["reward_error"] + info["reward_action"])


def test_force_action_reduces_error_when_it_opposes_friction() -> None:
    """Sanity of the action path: pushing with the motion beats pushing against it."""
    def run(sign: float) -> float:
        env = gym.make("fricbench/PaperAxis-v0")
        obs, _ = env.reset(seed=0, options={"trajectory": "s_curve"})
        errs = []
        for _ in range(env.unwrapped.reference.n_samples - 1):
            v_ref = obs[2]
            obs, _, _, trunc, info = env.step(np.array([sign * 0.6 * np.sign(v_ref)]))
            errs.append(abs(info["error_m"][0]))
            if trunc:
                break
        return max(errs)

    assert run(+1.0) < run(-1.0)


def test_offset_action_mode() -> None:
    spec = get_spec("fricbench/PaperAxis-v0")
    env = ServoAxisEnv(axis=spec.axis, task=replace(spec.task, action="offset",
                                                    action_scale=1e-4))
    env.reset(seed=0, options={"trajectory": "s_curve"})
    for _ in range(50):
        _, _, _, _, info = env.step(np.array([0.5]))
    # a 50 um constant reference offset moves the axis by 50 um
    assert info["error_m"][0] == pytest.approx(-5e-5, abs=3e-6)


def test_circle_env_measures_contour_error() -> None:
    env = gym.make("fricbench/CircleContouring-v0")
    obs, _ = env.reset(seed=0)
    assert env.action_space.shape == (2,)
    _, _, _, _, info = env.step(np.zeros(2))
    assert "contour_error_m" in info


def test_reset_option_errors() -> None:
    env = gym.make("fricbench/PaperAxis-v0")
    with pytest.raises(ValueError, match="unknown keys"):
        env.reset(options={"trajectry": "curve"})
    with pytest.raises(KeyError, match="did you mean"):
        env.reset(options={"trajectory": "m_seral"})
    with pytest.raises(ValueError, match="axes"):
        env.reset(options={"trajectory": "circle"})


def test_unstable_user_parameters_raise_clearly() -> None:
    spec = get_spec("fricbench/PaperAxis-v0")
    with pytest.raises(ValueError, match="controller.kv=5000 A s/m .*unstable"):
        spec.axis.with_controller(kv=5000.0, i_max=1e9)
    # the runtime check stays for what the construction check cannot see (gains packed by hand)
    env = ServoAxisEnv(axis=spec.axis, task=spec.task)
    env.reset(seed=0, options={"trajectory": "s_curve"})
    env.unwrapped._batch.P[:, K.P_KV] = 5000.0
    env.unwrapped._batch.P[:, K.P_IMAX] = 1e9
    with pytest.raises(SimulationDivergedError, match="unstable"):
        for _ in range(3000):
            env.step(np.zeros(1))


def test_render_rgb_array() -> None:
    env = gym.make("fricbench/PaperAxis-v0", render_mode="rgb_array")
    env.reset(seed=0, options={"trajectory": "s_curve"})
    for _ in range(20):
        env.step(np.zeros(1))
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    assert frame.std() > 0
    env.close()


@pytest.mark.parametrize("env_id", SINGLE)
def test_vector_env_matches_scalar_env(env_id: str) -> None:
    spec = get_spec(env_id)
    task = replace(spec.task, trajectories=(spec.task.trajectories[0],), randomize=type(
        spec.task.randomize)())
    # the spec's first trajectory, friction not redrawn: keywords merged onto the spec
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point",
                        trajectories=[spec.task.trajectories[0]],
                        randomize=dict.fromkeys(spec.task.randomize.ranges), reference_pool=1)
    assert venv.unwrapped.task == task and venv.unwrapped.axis == spec.axis
    vobs, _ = venv.reset(seed=0)
    env = ServoAxisEnv(axis=spec.axis, task=task)
    sobs, _ = env.reset(seed=0)
    np.testing.assert_allclose(vobs[0], sobs, rtol=1e-6, atol=1e-6)
    for _ in range(200):
        vobs, vr, *_ = venv.step(np.full((3, 1), 0.2, dtype=np.float32))
        sobs, sr, *_ = env.step(np.array([0.2], dtype=np.float32))
    np.testing.assert_allclose(vobs[1], sobs, rtol=1e-5, atol=1e-5)
    assert vr[1] == pytest.approx(sr, rel=1e-5, abs=1e-6)


def test_vector_env_autoresets() -> None:
    venv = gym.make_vec("fricbench/PaperAxis-v0", num_envs=2,
                        vectorization_mode="vector_entry_point", trajectories=["s_curve"])
    venv.reset(seed=0)
    n = 2540
    truncs = 0
    for _ in range(2 * n):
        _, _, _, trunc, _ = venv.step(np.zeros((2, 1), dtype=np.float32))
        truncs += int(trunc.sum())
    assert truncs >= 2


def test_new_toml_adds_an_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "mine.toml").write_text(
        'id = "fricbench/UserAxis-v0"\ndescription = "user"\n'
        '[axis.friction]\nid = "coulomb"\nfc = 100.0\n'
        '[task]\ntrajectories = ["s_curve"]\n')
    monkeypatch.setenv("FRICBENCH_ENV_PATH", str(tmp_path))
    assert "fricbench/UserAxis-v0" in register_envs()
    env = gym.make("fricbench/UserAxis-v0")
    env.reset(seed=0)
    assert env.unwrapped.axis.friction.fc == 100.0


def test_bad_toml_is_reported_with_file_and_key(tmp_path: Path) -> None:
    from fricbench.gym.specs import load_spec

    bad = tmp_path / "bad.toml"
    bad.write_text('id = "fricbench/Bad-v0"\n[axis.mechanics]\nmass = -1.0\n')
    with pytest.raises(ValueError, match="bad.toml.*mass"):
        load_spec(bad)
    bad.write_text('id = "fricbench/Bad-v0"\n[task]\naction = "torque"\n')
    with pytest.raises(ValueError, match="action"):
        load_spec(bad)


def test_specs_ship_inside_the_package() -> None:
    from importlib import resources

    shipped = resources.files("fricbench.gym").joinpath("specs")
    names = {p.name for p in Path(str(shipped)).glob("*.toml")}
    assert "paper_axis.toml" in names
    repo_envs = Path(fricbench.__file__).parents[1] / "envs"
    if repo_envs.is_dir():
        assert names == {p.name for p in repo_envs.glob("*.toml")}
