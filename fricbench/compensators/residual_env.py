"""The training env of ``rl-residual``: drawn plants, the ``kalman`` base, a residual action.

Two layers over fricbench's native vector env, neither of which changes it:

* :class:`PlantDrawingVectorEnv` draws a fresh plant for every episode of every sub-env from
  the benchmark's distribution (:func:`fricbench.axis.variation.draw_plant` around the training
  env's nominal axis: friction level, static excess ``fs - fc`` above Coulomb, Stribeck
  velocity, mass, damping; encoder noise), the plant seed drawn from the env's own seeded
  generator, and adds the current-measurement noise to the reported motor force as the scalar
  env does.
* :class:`ResidualVecEnv`, a stable-baselines3 ``VecEnv`` over it
  (:class:`~fricbench.gym.sb3.SB3VecEnv`), runs one :class:`~fricbench.compensators.
  residual_base.ObserverBank` row per sub-env: the agent sees the env's observation plus the
  base's estimate ``d_hat / F_s``, and its action ``r`` in [-1, 1] is added to the base's force,
  ``u = clip(-gain d_hat, +-F_max) + s_r r`` (then clipped to the env's action range). The
  reward is the env's with the action term on the residual only,
  ``-(e / e_s)^2 - w r^2``: the base's force is not the agent's to pay for.

The compensator (:class:`~fricbench.compensators.rl_residual.ResidualRLCompensator`) runs the
same bank, fed the same way (the float32 observation's error and motor force, the reference in
float64), so the base is the same at training and at benchmark time.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from fricbench._validation import check_int, check_nonneg, check_positive
from fricbench.axis import Axis
from fricbench.axis.variation import BENCH_VARIATION, PlantVariation, draw_plant, nominal_told
from fricbench.compensators.residual_base import ObserverBank
from fricbench.compensators.training_data import env_setup
from fricbench.gym.sb3 import SB3VecEnv
from fricbench.gym.task import Randomization, TaskConfig
from fricbench.gym.vector import ServoAxisVectorEnv

__all__ = ["PlantDrawingVectorEnv", "ResidualVecEnv", "make_residual_env",
           "training_distribution"]

_NOISE_TAG = 0x524553  # "RES": the current noise's stream, apart from the env's draws


def training_distribution(env_id: str, variation: PlantVariation = BENCH_VARIATION
                          ) -> dict[str, Any]:
    """What a residual policy trained on ``env_id`` saw, for its JSON (``training.residual``)."""
    axis, _ = env_setup(env_id)
    return {
        "plants": "draw_plant(nominal axis of env_id, seed) per episode (fricbench/bench/"
                  "plants.py): each parameter times exp(sigma z), z ~ N(0, 1) truncated to "
                  "|z| <= 2",
        "nominal_friction": axis.friction.to_dict(),
        "sigma": {"friction_level": variation.friction_level,
                  "static_excess": variation.static_excess,
                  "stribeck_velocity": variation.stribeck_velocity,
                  "mass": variation.mass, "damping": variation.damping},
        "encoder_noise_m": variation.encoder_noise,
        "current_noise_a": variation.current_noise,
        "references": "seeded random training mixture of env_id (never an evaluation "
                      "reference)",
    }


class PlantDrawingVectorEnv(ServoAxisVectorEnv):
    """:class:`~fricbench.gym.ServoAxisVectorEnv` with a plant drawn per episode.

    Each sub-env's episode runs on ``draw_plant(nominal, s, variation)`` with ``s`` drawn from
    the env's generator (so ``reset(seed=...)`` reproduces the plants too); the env's
    ``task.randomize`` must be empty (the plant draw replaces it).

    Parameters
    ----------
    num_envs : int
    nominal : Axis
        The nominal axis the plants are drawn around (noise free; the variation adds noise).
    task : TaskConfig
    variation : PlantVariation
    reference_pool, seed, autoreset_mode
        As for :class:`~fricbench.gym.ServoAxisVectorEnv`.
    """

    def __init__(self, num_envs: int, nominal: Axis, task: TaskConfig, *,
                 variation: PlantVariation = BENCH_VARIATION, reference_pool: int = 64,
                 seed: int = 0,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.SAME_STEP) -> None:
        if not isinstance(nominal, Axis):
            raise TypeError(f"nominal={nominal!r}: expected an Axis")
        if not isinstance(variation, PlantVariation):
            raise TypeError(f"variation={variation!r}: expected a PlantVariation")
        if task.randomize.ranges:
            raise ValueError(f"task.randomize={dict(task.randomize.ranges)!r}: expected none "
                             "(the plant is drawn from variation)")
        self.nominal = nominal
        self.variation = variation
        # the batch's template carries the noise levels, so that the step draws encoder noise
        super().__init__(num_envs, nominal_told(nominal, variation), task,
                         reference_pool=reference_pool, seed=seed,
                         autoreset_mode=autoreset_mode)

    def _reset_rows(self, rows: np.ndarray) -> None:
        idx = np.flatnonzero(rows)
        seeds = self._rng.integers(0, 2**31 - 1, idx.size)
        for i, s in zip(idx.tolist(), seeds.tolist(), strict=True):
            self._batch.set_params(i, draw_plant(self.nominal, s, self.variation))
        super()._reset_rows(rows)


class ResidualVecEnv(VecEnvWrapper):
    """Residual actions on top of the ``kalman`` base, over an :class:`SB3VecEnv` of a
    :class:`PlantDrawingVectorEnv` (``SAME_STEP`` autoreset).

    Observation: the env's features, then ``d_hat / force_scale``. Action: the residual in
    [-1, 1], ``residual_scale`` N per unit.

    Parameters
    ----------
    venv : SB3VecEnv
        Over a :class:`PlantDrawingVectorEnv`.
    residual_scale : float
        Newtons per unit residual action.
    bandwidth, gain : float
        The base observer's (``kalman``'s) settings.
    seed : int
        Seed of the current-measurement noise (re-seeded by :meth:`seed`).
    """

    def __init__(self, venv: SB3VecEnv, *, residual_scale: float = 400.0,
                 bandwidth: float = 1000.0, gain: float = 1.0, seed: int = 0) -> None:
        if not isinstance(venv, SB3VecEnv) or not isinstance(venv.venv, PlantDrawingVectorEnv):
            raise TypeError(f"venv={venv!r}: expected an SB3VecEnv over a "
                            "PlantDrawingVectorEnv (make_residual_env builds one)")
        if venv.venv.autoreset_mode != AutoresetMode.SAME_STEP:
            raise ValueError("venv: expected SAME_STEP autoreset")
        self.inner: PlantDrawingVectorEnv = venv.venv
        self.residual_scale = check_positive("residual_scale", residual_scale, "N")
        task = self.inner.task
        cfg = task.observation
        self._scale = task.action_scale
        self._e_s, self._f_s = cfg.error_scale, cfg.force_scale
        self._w = task.reward.action_weight
        told = self.inner.axis
        self._i_noise = told.controller.kt * self.inner.variation.current_noise / self._f_s
        self.bank = ObserverBank(told, venv.num_envs, bandwidth=bandwidth, gain=gain,
                                 max_force=self._scale)
        shape = venv.observation_space.shape
        if not shape:
            raise TypeError("venv: expected a Box observation space")
        nf = shape[0]
        obs_space = spaces.Box(-np.inf, np.inf, (nf + 1,), np.float32)
        super().__init__(venv, observation_space=obs_space, action_space=venv.action_space)
        self._noise_rng = np.random.default_rng([check_int("seed", seed, 0), _NOISE_TAG])
        self._actions: np.ndarray | None = None

    def seed(self, seed: int | None = None) -> Any:
        """Seed the env (at its next reset) and the current noise."""
        if seed is not None:
            self._noise_rng = np.random.default_rng([int(seed), _NOISE_TAG])
        return self.venv.seed(seed)

    def _noisy(self, obs: np.ndarray) -> np.ndarray:
        if self._i_noise > 0.0:
            # F_meas = kt (i + n_i): the drive reports a noisy current
            draws = self._noise_rng.standard_normal(obs.shape[0])
            obs[:, 6] += np.asarray(self._i_noise * draws, dtype=np.float32)
        return obs

    def _observe(self, obs: np.ndarray, ref_id: np.ndarray, k: np.ndarray,
                 rows: np.ndarray) -> np.ndarray:
        """Step the bank's ``rows`` on ``obs`` (their rows of the env's observation, already
        noisy) at reference sample ``k`` of ``ref_id``; the augmented observation."""
        o = obs.astype(np.float64)
        # z = x_ref - e (the reference in float64, as the compensator has it)
        z = self.inner._X[ref_id, k] - o[:, 0] * self._e_s
        self.bank.step(z, o[:, 6] * self._f_s, rows)
        return np.column_stack([obs, (self.bank.d_hat[rows] / self._f_s).astype(np.float32)])

    def reset(self) -> VecEnvObs:
        obs = self._noisy(np.asarray(self.venv.reset(), dtype=np.float32))
        env = self.inner
        rows = np.arange(self.num_envs)
        self.bank.reset(rows, env._X[env._ref_id, 0], env._V[env._ref_id, 0])
        return self._observe(obs, env._ref_id.copy(), env._k.copy(), rows)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float64).reshape(self.num_envs)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("call step_async(actions) before step_wait()")
        residual = np.clip(self._actions, -1.0, 1.0)
        self._actions = None
        env = self.inner
        ref_prev, k_next = env._ref_id.copy(), env._k + 1
        total = np.clip((self.bank.force() + self.residual_scale * residual) / self._scale,
                        -1.0, 1.0)
        self.venv.step_async(total[:, None].astype(np.float32))
        obs, rewards, dones, infos = self.venv.step_wait()
        obs = np.asarray(obs, dtype=np.float32)
        # r = -(e / e_s)^2 - w r^2: the env charged the total action; charge the residual
        rewards = (rewards.astype(np.float64) + self._w * total**2
                   - self._w * residual**2).astype(np.float32)
        done = np.flatnonzero(dones)
        # the sample each row's observation is at: the finished rows' is their last
        last = obs.copy()
        for i in done.tolist():
            last[i] = infos[i]["terminal_observation"]
        last = self._noisy(last)
        all_rows = np.arange(self.num_envs)
        aug = self._observe(last, ref_prev, k_next, all_rows)
        if done.size:
            for i in done.tolist():
                infos[i]["terminal_observation"] = aug[i].copy()
            fresh = self._noisy(obs[done].copy())
            self.bank.reset(done, env._X[env._ref_id[done], 0], env._V[env._ref_id[done], 0])
            aug[done] = self._observe(fresh, env._ref_id[done], env._k[done], done)
        return aug, rewards, dones, infos


def make_residual_env(env_id: str, num_envs: int, *, seed: int = 0, reference_pool: int = 64,
                      residual_scale: float = 400.0, bandwidth: float = 1000.0,
                      gain: float = 1.0,
                      variation: PlantVariation = BENCH_VARIATION) -> ResidualVecEnv:
    """The residual training env of ``env_id``: its nominal axis and references, plants drawn
    per episode from ``variation``, the ``kalman`` base (see the module docstring).

    Parameters
    ----------
    env_id : str
        A registered single-axis env (its ``task.randomize`` is replaced by the plant draw).
    num_envs : int
        Sub-envs.
    seed : int
        Seed of the reference pool, the episode draws (plants, references, encoder noise) and
        the current noise.
    reference_pool : int
        References per seeded trajectory choice.
    residual_scale : float
        Newtons per unit residual action.
    bandwidth, gain : float
        The base observer's settings.
    variation : PlantVariation
        The plant distribution.
    """
    check_int("num_envs", num_envs, 1)
    check_nonneg("gain", gain)
    axis, task = env_setup(env_id)
    task = replace(task, randomize=Randomization())
    inner = PlantDrawingVectorEnv(num_envs, axis, task, variation=variation,
                                  reference_pool=reference_pool, seed=seed)
    return ResidualVecEnv(SB3VecEnv(inner), residual_scale=residual_scale,
                          bandwidth=bandwidth, gain=gain, seed=seed)
