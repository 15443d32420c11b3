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

__all__ = ["ALGOS", "HYPERPARAMS", "VEC_ENVS", "TrainResult", "default_out", "train_agent",
           "export_actor", "make_training_env", "validation_score"]

#: compensator id -> stable-baselines3 algorithm
ALGOS = {"rl-sac": "sac", "rl-ppo": "ppo"}

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
                vec_env: str = "native") -> TrainResult:
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

    Raises
    ------
    FileExistsError
        Naming the file, when ``out`` names an existing policy file and not ``overwrite``.
    """
    check_choice("comp_id", comp_id, tuple(ALGOS))
    check_int("steps", steps, 1, 100_000_000)
    check_int("seed", seed, 0)
    check_choice("vec_env", vec_env, VEC_ENVS)
    algo = ALGOS[comp_id]
    json_path, weights_name = _out_paths(default_out(comp_id, seed) if out is None else out,
                                         comp_id)
    for path in (json_path, json_path.parent / weights_name):
        if path.exists() and not overwrite:
            raise FileExistsError(errno.EEXIST, "policy file exists; not overwritten", str(path))
    from stable_baselines3 import PPO, SAC

    torch.set_num_threads(1)
    hp = dict(HYPERPARAMS[algo])
    hp.update(overrides or {})
    n_envs = int(hp.pop("n_envs"))
    pool = int(hp.pop("reference_pool"))
    _, task = env_setup(env_id)
    vec = make_training_env(env_id, n_envs=n_envs, seed=seed, vec_env=vec_env,
                            reference_pool=pool)
    cls = SAC if algo == "sac" else PPO
    model = cls("MlpPolicy", vec, seed=seed, device="cpu", verbose=verbose, **hp)
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps)
    seconds = time.perf_counter() - t0
    vec.close()

    mlp, arch, activation, squash = export_actor(model, algo)
    obs_shape, act_shape = vec.observation_space.shape, vec.action_space.shape
    if not obs_shape or not act_shape:
        raise CompensatorError(f"{env_id}: expected Box observation and action spaces")
    obs_dim, act_dim = int(obs_shape[0]), int(act_shape[0])
    # the exported actor must reproduce stable-baselines3's deterministic action
    probe = np.random.default_rng(seed).standard_normal((64, obs_dim)).astype(np.float32)
    sb3_action, _ = model.predict(probe, deterministic=True)
    cmd = command or (f"fricbench train {comp_id} --env {env_id} --vec-env {vec_env} "
                      f"--steps {steps} --seed {seed} --out {json_path.with_suffix('')}")
    env_record = {"vec_env": vec_env, "n_envs": n_envs}
    if vec_env == "native":
        env_record["reference_pool"] = pool
    spec = PolicySpec(
        algo=algo, obs_dim=obs_dim, act_dim=act_dim,
        net_arch=tuple(arch), activation=activation, squash=squash, action_mode=task.action,
        action_scale=float(task.action_scale), env_id=env_id, weights=weights_name,
        training={"command": cmd, "seed": seed, "steps": steps, "seconds": round(seconds, 1),
                  **env_record, "hyperparameters": _jsonable(hp),
                  "versions": _versions()})
    save_policy(json_path, spec, mlp)
    exported = load_policy(json_path)(probe)
    diff = float(np.max(np.abs(exported - sb3_action)))
    if diff > 1e-4:
        raise CompensatorError(f"{json_path}: exported actor differs from the trained agent "
                               f"by {diff:g}")
    val = validation_score(json_path, env_id, seed=seed)
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
