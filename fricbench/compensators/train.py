"""Training of the RL compensators: ``fricbench train rl-sac --env ... --steps N --seed S``.

The agent learns on the training env (default ``fricbench/RandomFriction-v0``: friction
redrawn per episode, seeded ``random`` references; never an evaluation reference), stepped as
fricbench's native vector env through :class:`~fricbench.gym.sb3.SB3VecEnv` (each episode
draws its reference from a pool of ``reference_pool`` generated at the start), or as
stable-baselines3's ``DummyVecEnv`` of scalar envs (``vec_env="dummy"``, a fresh reference
every episode: how the shipped policies were trained). At the end the deterministic actor is
exported as plain weights plus a JSON (:mod:`fricbench.compensators.rl_policy`) that records
the exact command, seed, step count, wall time, library versions and hyperparameters, and a
validation score on fresh *training* references (the nominal axis of the training env, with
and without the policy).

Everything runs in one process with ``torch.set_num_threads(1)``; with the same seed, command
and library versions, a run reproduces its weights bit for bit on the same machine (the
shipped ones with ``--vec-env dummy``, the route their recorded commands took).
"""

from __future__ import annotations

import errno
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, replace
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import torch

from fricbench._validation import check_choice, check_int
from fricbench.compensators.base import CompensatorError
from fricbench.compensators.rl_policy import (
    PolicyMLP,
    PolicySpec,
    load_policy,
    save_policy,
)
from fricbench.compensators.training_data import env_setup, training_references
from fricbench.gym.env import ServoAxisEnv
from fricbench.gym.task import Randomization, n_features

__all__ = ["ALGOS", "HYPERPARAMS", "RESIDUAL", "RESIDUAL_HYPERPARAMS", "VEC_ENVS",
           "TrainResult", "default_out", "train_agent", "export_actor", "make_training_env",
           "residual_validation_score", "validation_score"]

#: compensator id -> stable-baselines3 algorithm (``rl-residual``: the default of ``algo``)
ALGOS = {"rl-sac": "sac", "rl-ppo": "ppo", "rl-residual": "ppo"}

#: ``rl-residual``'s base (``kalman``'s settings) and residual force per unit action, N
RESIDUAL: dict[str, float] = {"residual_scale": 400.0, "bandwidth": 1000.0, "gain": 1.0}

#: how the training env is vectorised: fricbench's native vector env, or stable-baselines3's
#: ``DummyVecEnv`` of scalar envs
VEC_ENVS = ("native", "dummy")

#: default hyperparameters (constructor keywords of the stable-baselines3 class, plus the
#: training env's ``n_envs`` and, for the native vector env, ``reference_pool``: references
#: generated at the start for the episodes to draw from)
HYPERPARAMS: dict[str, dict[str, Any]] = {
    "sac": {"n_envs": 1, "reference_pool": 64, "learning_rate": 3e-4, "buffer_size": 300_000,
            "learning_starts": 5_000, "batch_size": 256, "tau": 0.005, "gamma": 0.98,
            "train_freq": 1, "gradient_steps": 1, "ent_coef": "auto",
            "policy_kwargs": {"net_arch": [64, 64]}},
    "ppo": {"n_envs": 8, "reference_pool": 64, "learning_rate": 3e-4, "n_steps": 1024,
            "batch_size": 256, "n_epochs": 10, "gamma": 0.98, "gae_lambda": 0.95, "clip_range": 0.2,
            "ent_coef": 0.0, "policy_kwargs": {"net_arch": {"pi": [64, 64], "vf": [64, 64]},
                                               "log_std_init": -1.0}},
}


#: ``rl-residual``'s changes to :data:`HYPERPARAMS`: more sub-envs (a step of the native env
#: costs about the same for 1 or 32), and a smaller initial exploration: the residual starts
#: near zero on top of a base that already works
RESIDUAL_HYPERPARAMS: dict[str, dict[str, Any]] = {
    "ppo": {"n_envs": 32, "n_steps": 512, "batch_size": 1024,
            "policy_kwargs": {"net_arch": {"pi": [64, 64], "vf": [64, 64]},
                              "log_std_init": -1.5}},
    "sac": {"n_envs": 8, "learning_starts": 10_000},
}


@dataclass(frozen=True)
class TrainResult:
    """What a training run produced.

    Attributes
    ----------
    json_path, weights_path : Path
        The policy files.
    seconds : float
        Wall time of ``learn``, s.
    validation : dict
        Mean max |e| (um) on fresh training references with and without the policy.
    """

    json_path: Path
    weights_path: Path
    seconds: float
    validation: Mapping[str, float]


def default_out(comp_id: str, seed: int) -> Path:
    """Where a policy goes without ``out``: ``policies/<comp_id>-seed<seed>`` in the current
    directory (never the shipped ``fricbench/policies``)."""
    return Path("policies") / f"{comp_id}-seed{seed}"


def _out_paths(out: str | Path, comp_id: str) -> tuple[Path, str]:
    out = Path(out)
    if out.suffix in (".json", ".pt"):
        out = out.with_suffix("")
    if out.name.endswith(".*"):
        out = out.with_name(out.name[:-2])
    if out.name == "" or out.is_dir():
        out = out / comp_id
    return out.with_name(out.name + ".json"), out.name + ".pt"


def export_actor(model: Any, algo: str) -> tuple[PolicyMLP, list[int], str, str]:
    """The deterministic actor of a stable-baselines3 model as a :class:`PolicyMLP`.

    Returns the module, ``net_arch``, the activation name and the output squashing.
    """
    if algo == "sac":
        hidden, out = model.actor.latent_pi, model.actor.mu
        squash = "tanh"
    else:
        hidden, out = model.policy.mlp_extractor.policy_net, model.policy.action_net
        squash = "clip"
    linears = [m for m in hidden if isinstance(m, torch.nn.Linear)]
    acts = {type(m) for m in hidden if not isinstance(m, torch.nn.Linear)}
    if acts == {torch.nn.ReLU}:
        activation = "relu"
    elif acts == {torch.nn.Tanh}:
        activation = "tanh"
    else:
        raise CompensatorError(f"cannot export an actor with activations {acts}")
    arch = [m.out_features for m in linears]
    mlp = PolicyMLP(linears[0].in_features, out.out_features, arch, activation)
    mlp.hidden.load_state_dict(hidden.state_dict())
    mlp.out.load_state_dict(out.state_dict())
    return mlp, arch, activation, squash


def _rollout_max_error(env: ServoAxisEnv, reference: Any, policy: Any | None) -> float:
    """Max |e| (m) of one episode on ``reference`` with ``policy`` (None: no compensation)."""
    obs, _ = env.reset(seed=0, options={"trajectory": reference})
    nf = n_features(env.task.observation)
    worst = 0.0
    while True:
        if policy is None:
            action = np.zeros(1, dtype=np.float32)
        else:
            action = policy(obs[None, :nf])[0].astype(np.float32)
        obs, _, _, truncated, info = env.step(action)
        worst = max(worst, float(np.max(np.abs(info["error_m"]))))
        if truncated:
            return worst


def validation_score(json_path: str | Path, env_id: str, *, seed: int,
                     n: int = 3) -> dict[str, float]:
    """Mean max |e| (um) on ``n`` fresh training references, nominal axis of ``env_id``.

    The references are drawn with ``seed + 10_000`` (never those of training, never an
    evaluation reference).
    """
    axis, task = env_setup(env_id)
    env = ServoAxisEnv(axis=axis, task=replace(task, randomize=Randomization()))
    pol = load_policy(json_path)
    refs = training_references(n, seed=seed + 10_000, duration=10.0, ts=axis.controller.ts)
    none = [_rollout_max_error(env, r, None) for r in refs]
    with_pol = [_rollout_max_error(env, r, pol) for r in refs]
    return {"none_max_um": 1e6 * float(np.mean(none)),
            "policy_max_um": 1e6 * float(np.mean(with_pol)),
            "improvement_pct": 100.0 * (1.0 - float(np.mean(with_pol)) / float(np.mean(none)))}


def residual_validation_score(json_path: str | Path, env_id: str, *, seed: int,
                              n: int = 4) -> dict[str, float]:
    """Mean max |e| (um) of ``rl-residual`` with the policy ``json_path``, of its base alone
    (``kalman``) and of no compensation, on ``n`` fresh training references, each on its own
    plant drawn as in training.

    The references are drawn with ``seed + 10_000`` and the plants with the seeds
    ``10_000 + seed * n + i`` (far from the benchmark's plants of seeds 0, 1, ...): neither is
    seen in training nor scored by the benchmark.
    """
    from fricbench.axis.variation import draw_plant, nominal_told
    from fricbench.compensators import make_compensator

    axis, task = env_setup(env_id)
    task = replace(task, randomize=Randomization())
    refs = training_references(n, seed=seed + 10_000, duration=10.0, ts=axis.controller.ts)
    comps = {"none": make_compensator("none"), "base": make_compensator("kalman"),
             "policy": make_compensator("rl-residual", policy=str(json_path))}
    worst: dict[str, list[float]] = {key: [] for key in comps}
    for i, ref in enumerate(refs):
        plant = draw_plant(axis, 10_000 + seed * n + i)
        for key, comp in comps.items():
            comp.fit(env_id, seed=seed)
            env = ServoAxisEnv(axis=nominal_told(axis), task=task, plant=plant)
            obs, _ = env.reset(seed=i, options={"trajectory": ref})
            comp.reset(env.episode_context(), seed=i)
            peak = 0.0
            while True:
                obs, _, _, truncated, info = env.step(comp.act(obs))
                peak = max(peak, float(np.max(np.abs(info["error_m"]))))
                if truncated:
                    break
            worst[key].append(peak)
    mean = {key: float(np.mean(v)) for key, v in worst.items()}
    return {"none_max_um": 1e6 * mean["none"], "base_max_um": 1e6 * mean["base"],
            "policy_max_um": 1e6 * mean["policy"],
            "improvement_pct": 100.0 * (1.0 - mean["policy"] / mean["none"]),
            "improvement_over_base_pct": 100.0 * (1.0 - mean["policy"] / mean["base"])}


def _load_average() -> list[float] | None:
    """The machine's 1, 5 and 15 min load averages at the end of training (None if unknown)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def make_training_env(env_id: str, *, n_envs: int, seed: int, vec_env: str = "native",
                      reference_pool: int = 64) -> Any:
    """The stable-baselines3 ``VecEnv`` an agent trains on, with episode statistics.

    Parameters
    ----------
    env_id : str
        Training env.
    n_envs : int
        Parallel sub-envs.
    seed : int
        Seed of the env resets (and of the native env's reference pool).
    vec_env : {"native", "dummy"}
        ``"native"``: :func:`fricbench.gym.sb3.make_sb3_vec_env` in a ``VecMonitor`` (all
        sub-envs in one compiled step; each episode's reference drawn from a pool of
        ``reference_pool``). ``"dummy"``: ``make_vec_env`` (a ``DummyVecEnv`` of scalar envs in
        ``Monitor``; a fresh reference every episode).
    reference_pool : int
        References per seeded trajectory choice of the native env.
    """
    check_choice("vec_env", vec_env, VEC_ENVS)
    if vec_env == "dummy":
        from stable_baselines3.common.env_util import make_vec_env

        return make_vec_env(env_id, n_envs=n_envs, seed=seed)
    from stable_baselines3.common.vec_env import VecMonitor

    from fricbench.gym.sb3 import make_sb3_vec_env

    return VecMonitor(make_sb3_vec_env(env_id, n_envs, seed=seed,
                                       reference_pool=reference_pool))


def _versions() -> dict[str, str]:
    out = {}
    for pkg in ("stable-baselines3", "torch", "gymnasium", "numpy", "fricbench"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "unknown"
    return out


def train_agent(comp_id: str, *, env_id: str = "fricbench/RandomFriction-v0",
                steps: int = 200_000, seed: int = 0, out: str | Path | None = None,
                command: str = "", overrides: Mapping[str, Any] | None = None,
                verbose: int = 0, overwrite: bool = False,
                vec_env: str = "native", algo: str | None = None) -> TrainResult:
    """Train ``comp_id``'s agent on ``env_id`` and write the policy files.

    Parameters
    ----------
    comp_id : {"rl-sac", "rl-ppo"}
        Which compensator's policy.
    env_id : str
        Training env (its training references only).
    steps : int
        Environment steps (summed over the parallel envs).
    seed : int
        Seed of the agent, the env resets and the training references.
    out : str or Path, optional
        Output stem (``.../rl-sac`` -> ``rl-sac.json`` + ``rl-sac.pt``) or a folder; default
        :func:`default_out`.
    command : str
        The command line to record (default: the equivalent ``fricbench train`` call).
    overrides : mapping, optional
        Hyperparameters replacing :data:`HYPERPARAMS` entries.
    verbose : int
        stable-baselines3 verbosity.
    overwrite : bool
        Replace existing policy files; without it an existing file is an error, raised before
        any training.
    vec_env : {"native", "dummy"}
        How the training env is vectorised (:func:`make_training_env`); the shipped policies
        were trained with ``"dummy"``.
    algo : {"sac", "ppo"}, optional
        The algorithm; ``None``: ``ALGOS[comp_id]``. Only ``rl-residual`` takes either (the
        others name theirs).

    Raises
    ------
    FileExistsError
        Naming the file, when ``out`` names an existing policy file and not ``overwrite``.
    """
    check_choice("comp_id", comp_id, tuple(ALGOS))
    check_int("steps", steps, 1, 100_000_000)
    check_int("seed", seed, 0)
    check_choice("vec_env", vec_env, VEC_ENVS)
    residual = comp_id == "rl-residual"
    if algo is None:
        algo = ALGOS[comp_id]
    check_choice("algo", algo, ("sac", "ppo"))
    if not residual and algo != ALGOS[comp_id]:
        raise ValueError(f"algo={algo!r}: {comp_id} is trained with {ALGOS[comp_id]!r}")
    if residual and vec_env != "native":
        raise ValueError(f"vec_env={vec_env!r}: rl-residual trains on the native vector env "
                         "(its base observer runs over all sub-envs); expected 'native'")
    _, task = env_setup(env_id)
    scored = [c.id for c in task.trajectories if not c.seeded]
    if scored:
        # an env's fixed references are what the benchmark scores it on: learning on them is
        # evaluating on the training data
        raise ValueError(f"env_id={env_id!r}: its references ({', '.join(scored)}) are fixed "
                         "ones the benchmark scores; expected an env of seeded 'random' "
                         "training references, such as fricbench/RandomFriction-v0")
    json_path, weights_name = _out_paths(default_out(comp_id, seed) if out is None else out,
                                         comp_id)
    for path in (json_path, json_path.parent / weights_name):
        if path.exists() and not overwrite:
            raise FileExistsError(errno.EEXIST, "policy file exists; not overwritten", str(path))
    from stable_baselines3 import PPO, SAC

    torch.set_num_threads(1)
    hp = dict(HYPERPARAMS[algo])
    hp.update(RESIDUAL_HYPERPARAMS[algo] if residual else {})
    hp.update(overrides or {})
    res_cfg = {k: float(hp.pop(k, v)) for k, v in RESIDUAL.items()} if residual else {}
    n_envs = int(hp.pop("n_envs"))
    pool = int(hp.pop("reference_pool"))
    if residual:
        from stable_baselines3.common.vec_env import VecMonitor

        from fricbench.compensators.residual_env import make_residual_env

        vec = VecMonitor(make_residual_env(
            env_id, n_envs, seed=seed, reference_pool=pool,
            residual_scale=res_cfg["residual_scale"], bandwidth=res_cfg["bandwidth"],
            gain=res_cfg["gain"]))
    else:
        vec = make_training_env(env_id, n_envs=n_envs, seed=seed, vec_env=vec_env,
                                reference_pool=pool)
    cls = SAC if algo == "sac" else PPO
    model = cls("MlpPolicy", vec, seed=seed, device="cpu", verbose=verbose, **hp)
    load_start = _load_average()
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps)
    seconds = time.perf_counter() - t0
    load_end = _load_average()
    vec.close()

    mlp, arch, activation, squash = export_actor(model, algo)
    obs_shape, act_shape = vec.observation_space.shape, vec.action_space.shape
    if not obs_shape or not act_shape:
        raise CompensatorError(f"{env_id}: expected Box observation and action spaces")
    obs_dim, act_dim = int(obs_shape[0]), int(act_shape[0])
    # the exported actor must reproduce stable-baselines3's deterministic action
    probe = np.random.default_rng(seed).standard_normal((64, obs_dim)).astype(np.float32)
    sb3_action, _ = model.predict(probe, deterministic=True)
    algo_opt = f" --algo {algo}" if residual else ""
    cmd = command or (f"fricbench train {comp_id}{algo_opt} --env {env_id} --vec-env {vec_env} "
                      f"--steps {steps} --seed {seed} --out {json_path.with_suffix('')}")
    env_record: dict[str, Any] = {"vec_env": vec_env, "n_envs": n_envs}
    if vec_env == "native":
        env_record["reference_pool"] = pool
    # the machine's load (1, 5, 15 min) before and after: the wall time depends on it
    env_record["load_average"] = {"start": load_start, "end": load_end}
    scale = float(task.action_scale)
    if residual:
        from fricbench.compensators.residual_env import training_distribution

        scale = res_cfg["residual_scale"]
        env_record["residual"] = {
            "base": {"id": "kalman", "bandwidth": res_cfg["bandwidth"],
                     "gain": res_cfg["gain"]},
            "residual_scale_n": scale,
            "observation": "the env's features, then d_hat / force_scale (the base's estimate)",
            "reward": "-(e / error_scale)^2 - action_weight r^2 (r: the residual action)",
            **training_distribution(env_id)}
    spec = PolicySpec(
        algo=algo, obs_dim=obs_dim, act_dim=act_dim,
        net_arch=tuple(arch), activation=activation, squash=squash, action_mode=task.action,
        action_scale=scale, env_id=env_id, weights=weights_name,
        training={"command": cmd, "seed": seed, "steps": steps, "seconds": round(seconds, 1),
                  **env_record, "hyperparameters": _jsonable(hp),
                  "versions": _versions()})
    save_policy(json_path, spec, mlp)
    exported = load_policy(json_path)(probe)
    diff = float(np.max(np.abs(exported - sb3_action)))
    if diff > 1e-4:
        raise CompensatorError(f"{json_path}: exported actor differs from the trained agent "
                               f"by {diff:g}")
    val = (residual_validation_score(json_path, env_id, seed=seed) if residual
           else validation_score(json_path, env_id, seed=seed))
    spec = PolicySpec(**{**spec.__dict__, "training": {**spec.training, "validation": val}})
    save_policy(json_path, spec, mlp)
    return TrainResult(json_path, json_path.parent / weights_name, seconds, val)


def _jsonable(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (int, float, str, bool)) or value is None:
        return value
    return repr(value)
