"""rl-residual: the vectorised base is kalman's, the residual adds to it, safe files, errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from fricbench.axis.variation import PlantVariation, draw_plant, nominal_told
from fricbench.bench.runner import bench_env
from fricbench.compensators import CompensatorError, make_compensator
from fricbench.compensators.residual_base import ObserverBank, gain_schedule
from fricbench.compensators.residual_env import make_residual_env
from fricbench.compensators.rl import shipped_policy
from fricbench.compensators.rl_policy import PolicyMLP, PolicySpec, save_policy
from fricbench.compensators.train import train_agent
from fricbench.gym import ServoAxisEnv, get_spec
from fricbench.trajectories import Reference

ENV = "fricbench/PaperAxis-v0"
# the float32 action of Compensator.act: half a unit in the last place at |a| <= 1
F32_TOL = 6e-8


def _residual_policy(tmp_path: Path, zero: bool, obs_dim: int = 18) -> Path:
    """A residual policy file; ``zero``: its output layer is zero (the residual is 0)."""
    torch.manual_seed(0)
    mlp = PolicyMLP(obs_dim, 1, (8, 8), "tanh")
    if zero:
        with torch.no_grad():
            mlp.out.weight.zero_()
            mlp.out.bias.zero_()
    spec = PolicySpec(algo="ppo", obs_dim=obs_dim, act_dim=1, net_arch=(8, 8),
                      activation="tanh", squash="clip", action_mode="force", action_scale=400.0,
                      env_id="fricbench/RandomFriction-v0", weights="r.pt",
                      training={"residual": {"base": {"id": "kalman", "bandwidth": 1000.0,
                                                      "gain": 1.0}}})
    path = tmp_path / "r.json"
    save_policy(path, spec, mlp)
    return path


def _run_pair(a_comp, b_comp, env_id: str = ENV, seed: int = 3,
              trajectory: str = "s_curve") -> tuple[np.ndarray, np.ndarray]:
    """Actions of two compensators on the same observations (the env driven by ``a``)."""
    env = bench_env(env_id, a_comp, seed=seed)
    obs, _ = env.reset(seed=seed, options={"trajectory": trajectory})
    ctx = env.episode_context()
    a_comp.reset(ctx, seed=seed)
    b_comp.reset(ctx, seed=seed)
    acts_a, acts_b = [], []
    while True:
        a, b = a_comp.act(obs), b_comp.act(obs)
        acts_a.append(a)
        acts_b.append(b)
        obs, _, _, truncated, _ = env.step(a)
        if truncated:
            return np.array(acts_a), np.array(acts_b)


def test_bank_gives_kalmans_force() -> None:
    """The observer bank reproduces kalman to the float32 action's rounding, on a drawn plant
    with encoder and current noise (kalman against filterpy: tests/compensators/
    test_kalman.py)."""
    kal = make_compensator("kalman").fit(ENV)
    env = bench_env(ENV, kal, seed=5)
    obs, _ = env.reset(seed=5, options={"trajectory": "s_curve"})
    ctx = env.episode_context()
    kal.reset(ctx, seed=5)
    ref, cfg, scale = ctx.reference, ctx.task.observation, ctx.task.action_scale
    bank = ObserverBank(ctx.nominal_axis, 2, max_force=scale)  # row 1: a copy, same input
    bank.reset(np.array([0, 1]), ref.x[:1].repeat(2), ref.v[:1].repeat(2))
    worst, k = 0.0, 0
    while True:
        a = kal.act(obs)
        e, f = np.float64(obs[0]) * cfg.error_scale, np.float64(obs[6]) * cfg.force_scale
        bank.step(np.full(2, ref.x[k] - e), np.full(2, f))
        force = bank.force()
        assert force[0] == force[1]
        worst = max(worst, abs(force[0] / scale - float(a[0])))
        obs, _, _, truncated, _ = env.step(a)
        k += 1
        if truncated:
            break
    assert worst <= F32_TOL, worst


def test_gain_schedule_settles() -> None:
    gains = gain_schedule(nominal_told(get_spec(ENV).axis), 1000.0)
    assert 2 < len(gains) < 2000
    assert np.all(np.isfinite(gains))


def test_zero_residual_is_the_base(tmp_path: Path) -> None:
    """With a policy whose output is 0 the compensator's action is kalman's, sample by sample,
    on one axis and on the two-axis circle."""
    res = make_compensator("rl-residual", policy=_residual_policy(tmp_path, zero=True)).fit(ENV)
    kal = make_compensator("kalman").fit(ENV)
    a_kal, a_res = _run_pair(kal, res)
    assert a_kal.shape == a_res.shape
    assert np.max(np.abs(a_kal - a_res)) <= F32_TOL
    a_kal, a_res = _run_pair(kal, res, "fricbench/CircleContouring-v0", trajectory="circle")
    assert a_kal.shape[1] == 2 and np.max(np.abs(a_kal - a_res)) <= F32_TOL


def test_residual_adds_to_the_base(tmp_path: Path) -> None:
    """A non-zero policy moves the action away from the base by its scaled output."""
    res = make_compensator("rl-residual", policy=_residual_policy(tmp_path, zero=False)).fit(ENV)
    kal = make_compensator("kalman").fit(ENV)
    a_kal, a_res = _run_pair(kal, res)
    assert np.max(np.abs(a_kal - a_res)) > 1e-3


@pytest.mark.parametrize("env_id", [ENV, "fricbench/EMPS-v0"])
def test_residual_is_read_in_the_envs_force_unit(tmp_path: Path, env_id: str) -> None:
    """A constant output r adds r s_r F_s / F_s,train newtons: the JSON's 400 N per unit on an
    env of the training env's size (F_s 1000 N); on EMPS-v0 (F_s 152 N, another loop and a
    quarter of the mass) the residual is off: the base's action alone."""
    path = _residual_policy(tmp_path, zero=True)
    state = torch.load(tmp_path / "r.pt", weights_only=True)
    state["out.bias"] = torch.tensor([0.05])
    torch.save(state, tmp_path / "r.pt")
    res = make_compensator("rl-residual", policy=path).fit(env_id)
    kal = make_compensator("kalman").fit(env_id)
    a_kal, a_res = _run_pair(kal, res, env_id)
    if env_id != ENV:
        assert res.residual_off_ and np.array_equal(a_kal, a_res)
        return
    task = get_spec(env_id).task
    step = 0.05 * 400.0 * task.observation.force_scale / 1000.0 / task.action_scale
    inside = np.abs(a_kal[:, 0] + step) < 1.0  # where neither action is clipped
    assert inside.sum() > 100
    assert np.max(np.abs(a_res[inside, 0] - a_kal[inside, 0] - step)) <= 4 * F32_TOL


def test_training_env_base_is_the_compensators() -> None:
    """The training wrapper's base, at zero residual, acts exactly as the compensator's would
    on the same plant and reference (noise off so that both runs see the same machine)."""
    quiet = PlantVariation(encoder_noise=0.0, current_noise=0.0)
    vec = make_residual_env("fricbench/RandomFriction-v0", 1, seed=4, reference_pool=2,
                            variation=quiet)
    obs = vec.reset()
    inner = vec.inner
    plant = inner._batch.axes[0]
    i, n = int(inner._ref_id[0]), int(inner._len[inner._ref_id[0]])
    ts = inner.ts
    ref = Reference(t=ts * np.arange(n), x=inner._X[i, :n].copy(), v=inner._V[i, :n].copy(),
                    a=inner._A[i, :n].copy(), name="pool")
    spec = get_spec("fricbench/RandomFriction-v0")
    env = ServoAxisEnv(axis=spec.axis, task=inner.task, plant=plant)
    obs1, _ = env.reset(seed=0, options={"trajectory": ref})
    kal = make_compensator("kalman").fit(ENV)
    kal.reset(env.episode_context(), seed=0)
    for _ in range(400):
        np.testing.assert_array_equal(obs[0, :-1], obs1)
        a = kal.act(obs1)
        # what the wrapper applies at zero residual: the base's force as a float32 action
        applied = np.clip(vec.bank.force() / inner.task.action_scale, -1, 1).astype(np.float32)
        assert abs(float(applied[0]) - float(a[0])) <= F32_TOL
        obs, *_ = vec.step(np.zeros((1, 1), dtype=np.float32))
        obs1, *_ = env.step(applied)


def test_training_env_seeded_and_draws_plants() -> None:
    def roll(seed: int) -> tuple[np.ndarray, list[float]]:
        vec = make_residual_env("fricbench/RandomFriction-v0", 4, seed=seed, reference_pool=2)
        vec.seed(seed)
        out = [vec.reset()]
        rng = np.random.default_rng(0)
        for _ in range(50):
            o, r, _, _ = vec.step(rng.uniform(-1, 1, (4, 1)).astype(np.float32))
            out.append(o)
            assert r.dtype == np.float32 and np.all(np.isfinite(r))
        masses = [ax.mechanics.mass for ax in vec.inner._batch.axes]
        return np.array(out), masses

    a, ma = roll(1)
    b, mb = roll(1)
    c, _ = roll(2)
    assert a.shape == (51, 4, 18)
    np.testing.assert_array_equal(a, b)
    assert ma == mb and len(set(ma)) == 4  # a plant of its own per sub-env
    assert not np.array_equal(a, c)


def test_shipped_policy_loads_weights_only() -> None:
    json_path = shipped_policy("rl-residual")
    state = torch.load(json_path.with_suffix(".pt"), weights_only=True)
    assert all(isinstance(v, torch.Tensor) for v in state.values())
    data = json.loads(json_path.read_text())
    training = data["training"]
    assert training["residual"]["base"]["id"] == "kalman"
    assert "sigma" in training["residual"] and training["seconds"] <= 1800
    comp = make_compensator("rl-residual").fit(ENV)
    assert comp.policy_.spec.obs_dim == 18


def test_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match="policy"):
        make_compensator("rl-residual", policy=3)
    with pytest.raises(ValueError, match="policy"):
        make_compensator("rl-residual", policy="")
    # a whole-force policy is not a residual one
    with pytest.raises(CompensatorError, match="residual"):
        make_compensator("rl-residual", policy=shipped_policy("rl-ppo")).fit(ENV)
    with pytest.raises(CompensatorError, match="obs_dim"):
        make_compensator("rl-residual",
                         policy=_residual_policy(tmp_path, zero=True, obs_dim=17)).fit(ENV)
    axis = get_spec(ENV).axis
    with pytest.raises(ValueError, match="n="):
        ObserverBank(axis, 0)
    with pytest.raises(ValueError, match="bandwidth"):
        ObserverBank(axis, 1, bandwidth=-1.0)
    with pytest.raises(TypeError, match="axis"):
        ObserverBank("axis", 1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="residual_scale"):
        make_residual_env("fricbench/RandomFriction-v0", 1, residual_scale=0.0)
    with pytest.raises(ValueError, match="num_envs"):
        make_residual_env("fricbench/RandomFriction-v0", 0)
    with pytest.raises(ValueError, match="algo"):
        train_agent("rl-sac", algo="ppo", steps=10, out=tmp_path / "x")
    with pytest.raises(ValueError, match="vec_env"):
        train_agent("rl-residual", vec_env="dummy", steps=10, out=tmp_path / "x")


def test_plant_draw_is_the_benchmarks() -> None:
    """The training env's plants come from the benchmark's distribution around its nominal."""
    vec = make_residual_env("fricbench/RandomFriction-v0", 3, seed=0, reference_pool=1)
    vec.reset()
    nominal = get_spec("fricbench/RandomFriction-v0").axis
    for ax in vec.inner._batch.axes:
        fr = ax.friction.to_dict()
        assert fr["fs"] > fr["fc"]  # stiction above Coulomb
        assert ax.effects.noise_std == 1e-7
        ratio = ax.mechanics.mass / nominal.mechanics.mass
        assert np.exp(-0.1) - 1e-12 <= ratio <= np.exp(0.1) + 1e-12
    assert draw_plant(nominal, 0) == draw_plant(nominal, 0)


def test_check_setup_loads_the_policy_without_fitting(tmp_path: Path) -> None:
    make_compensator("rl-residual").check_setup(ENV)  # the shipped policy suits the env
    comp = make_compensator("rl-residual", policy=str(tmp_path / "missing.json"))
    with pytest.raises(CompensatorError, match="missing.json: cannot read policy JSON"):
        comp.check_setup(ENV)
    sac = tmp_path / "sac.json"  # not a residual policy: no base recorded
    sac.write_text(shipped_policy("rl-sac").read_text())
    (tmp_path / "rl-sac.pt").write_bytes(shipped_policy("rl-sac").with_suffix(".pt").read_bytes())
    with pytest.raises(CompensatorError, match="sac.json"):
        make_compensator("rl-residual", policy=str(sac)).check_setup(ENV)
    assert not hasattr(comp, "policy_")  # nothing kept: fit() still required

def test_outside_its_training_axis_the_residual_is_off_and_the_base_acts_alone() -> None:
    """On the EMPS twin (another loop, a quarter of the mass) the shipped residual is off:
    every action is kalman's, bit for bit, alone and stepped in a batch; the table is told
    why. On the paper axis it acts."""
    emps = "fricbench/EMPS-v0"
    res = make_compensator("rl-residual").fit(emps)
    assert "linear control law" in res.residual_off_ and "mass" in res.residual_off_
    note = make_compensator("rl-residual").env_note(emps)
    assert "`kalman` alone" in note and "RandomFriction-v0" in note
    a_res, a_kal = _run_pair(res, make_compensator("kalman").fit(emps), emps,
                             trajectory="reversal_sine")
    assert np.array_equal(a_res, a_kal)
    members = []
    for seed in (1, 2):
        comp = make_compensator("rl-residual").fit(emps)
        env = bench_env(emps, comp, seed=seed)
        obs, _ = env.reset(seed=seed, options={"trajectory": "reversal_sine"})
        comp.reset(env.episode_context(), seed=seed)
        members.append((comp, obs))
    batch = type(members[0][0]).batch([m for m, _ in members])
    assert type(batch).__name__ == "_KalmanBatch"
    paper = make_compensator("rl-residual").fit(ENV)
    assert paper.residual_off_ == "" and paper.env_note(ENV) == ""


def test_residual_scope_names_what_lies_outside_the_training_plants() -> None:
    from dataclasses import replace

    from fricbench.compensators.rl_residual import residual_scope

    axis = get_spec(ENV).axis
    sigma = {"mass": 0.05, "damping": 0.2}
    assert residual_scope(axis, axis, sigma) == ""
    # within exp(2 sigma) of the mass: in; beyond: out, with the range
    heavier = replace(axis, mechanics=replace(axis.mechanics, mass=440.0))
    assert residual_scope(axis, heavier, sigma) == ""
    heavier = replace(axis, mechanics=replace(axis.mechanics, mass=450.0))
    assert "mass 450 kg lies outside" in residual_scope(axis, heavier, sigma)
    # the substeps are the simulation's, not the loop's; a gain is the loop's
    finer = replace(axis, controller=replace(axis.controller, n_substeps=10))
    assert residual_scope(axis, finer, sigma) == ""
    other = replace(axis, controller=replace(axis.controller, kp=100.0))
    assert "kp=100" in residual_scope(axis, other, sigma)
