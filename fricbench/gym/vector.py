"""``ServoAxisVectorEnv``: N single-axis envs stepped together by the batched kernel."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from fricbench.axis import Axis, AxisBatch
from fricbench.gym.task import (
    TaskConfig,
    check_action,
    fill_observation,
    n_features,
    obs_scales,
    preview_offsets,
    reference_for,
    stack_references,
)

__all__ = ["ServoAxisVectorEnv"]


class ServoAxisVectorEnv(VectorEnv):
    """A native vector version of :class:`~fricbench.gym.env.ServoAxisEnv` (single axis).

    All sub-envs share one :class:`~fricbench.axis.AxisBatch`, so a step is one kernel call for
    every axis (parallel over cores above 256 envs). References come from a pool generated at
    construction (``reference_pool`` per seeded trajectory choice, e.g. ``random``), and each
    sub-env draws from the pool at reset. Observations, actions and rewards are those of the
    scalar env; autoreset follows Gymnasium's ``NEXT_STEP`` mode.

    Parameters
    ----------
    num_envs : int
        Number of sub-envs.
    axis : Axis
    task : TaskConfig
    reference_pool : int
        References generated per seeded trajectory choice.
    seed : int
        Seed of the reference pool.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, axis: Axis | None = None,
                 task: TaskConfig | None = None, reference_pool: int = 4, seed: int = 0,
                 render_mode: str | None = None) -> None:
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs={num_envs!r}: expected an integer >= 1")
        if render_mode is not None:
            raise ValueError("render_mode: the vector env does not render; use ServoAxisEnv")
        self.axis = Axis() if axis is None else axis
        self.task = TaskConfig() if task is None else task
        self.num_envs = num_envs
        self.ts = self.axis.controller.ts
        cfg = self.task.observation
        self._offsets = preview_offsets(cfg).astype(np.int64)
        self._scales = obs_scales(cfg)
        pool_rng = np.random.default_rng(seed)
        refs = []
        for choice in self.task.trajectories:
            for _ in range(reference_pool if choice.seeded else 1):
                refs.append(reference_for(choice, self.ts, pool_rng))
        if any(r.n_axes != 1 for r in refs):
            raise ValueError("ServoAxisVectorEnv drives single-axis references only")
        pad = int(self._offsets[-1]) if self._offsets.size else 0
        self._X, self._V, self._A, self._len = stack_references(refs, pad)
        self._names = [r.name for r in refs]
        self._nf = n_features(cfg)
        self.single_observation_space = spaces.Box(-np.inf, np.inf, (self._nf,), np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._batch = AxisBatch(self.axis, n=num_envs)
        n = num_envs
        self._ref_id = np.zeros(n, dtype=np.int64)
        self._k = np.zeros(n, dtype=np.int64)
        self._prev_action = np.zeros(n)
        self._u_force = np.zeros((n, 1))
        self._u_off = np.zeros((n, 1))
        self._noise = np.zeros((n, 1))
        self._obs = np.zeros((n, self._nf))
        self._autoreset = np.zeros(n, dtype=bool)
        self._out = tuple(np.empty((n, 1)) for _ in range(4))
        self._xr = np.empty((n, 1))
        self._vr = np.empty((n, 1))
        self._ar = np.empty((n, 1))
        self._np_random = np.random.default_rng(seed)

    def _reset_rows(self, rows: np.ndarray) -> None:
        idx = np.flatnonzero(rows)
        if idx.size == 0:
            return
        rng = self._np_random
        self._ref_id[idx] = rng.integers(0, self._X.shape[0], idx.size)
        self._k[idx] = 0
        self._prev_action[idx] = 0.0
        if self.task.randomize.ranges:
            for i in idx:
                self._batch.set_params(int(i), self.task.randomize.sample(self.axis, rng))
        noise = rng.standard_normal(idx.size) if self.axis.needs_noise else None
        self._batch.reset(self._X[self._ref_id[idx], 0], self._V[self._ref_id[idx], 0], noise,
                          rows=idx)

    def reset(self, *, seed: int | list[int] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        if isinstance(seed, list):
            seed = seed[0] if seed else None
        if seed is not None:
            self._np_random = np.random.default_rng(seed)
        if options:
            raise ValueError(f"reset options {sorted(options)}: the vector env takes none")
        self._reset_rows(np.ones(self.num_envs, dtype=bool))
        self._autoreset[:] = False
        return self._observation(), {}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                 dict[str, Any]]:
        a = check_action(actions, (self.num_envs, 1))[:, 0]
        pending = self._autoreset.any()
        if pending:
            self._reset_rows(self._autoreset)
            live = ~self._autoreset
            act = np.where(live, a, 0.0)
        else:
            act = a
        rid, k = self._ref_id, self._k
        self._xr[:, 0] = self._X[rid, k]
        self._vr[:, 0] = self._V[rid, k]
        self._ar[:, 0] = self._A[rid, k]
        target = self._u_force if self.task.action == "force" else self._u_off
        np.multiply(act, self.task.action_scale, out=target[:, 0])
        if self.axis.needs_noise:
            self._noise[:, 0] = self._np_random.standard_normal(self.num_envs)
        if pending:
            # rows that were just reset do not advance: their observation is the reset one
            self._step_live(live)
            self._k = np.where(live, k + 1, k)
        else:
            self._batch.run(self._xr, self._vr, self._ar, self._u_force, self._u_off,
                            self._noise, out=self._out)
            self._k = k + 1
        self._prev_action = act
        obs = self._observation()
        err = obs[:, 0].astype(np.float64) * self.task.observation.error_scale
        rewards = -(err / self.task.reward.error_scale) ** 2 \
            - self.task.reward.action_weight * act**2
        truncated = self._k >= self._len[rid] - 1
        if pending:
            rewards[~live] = 0.0
            truncated &= live
        terminated = np.zeros(self.num_envs, dtype=bool)
        self._autoreset = truncated.copy()
        return obs, rewards, terminated, truncated, {}

    def _step_live(self, live: np.ndarray) -> None:
        # sub-batches are rare (only on autoreset steps): run all rows, then restore the states
        # of the rows that must not move
        saved = self._batch.S[~live].copy()
        self._batch.run(self._xr, self._vr, self._ar, self._u_force, self._u_off, self._noise,
                        out=self._out)
        self._batch.S[~live] = saved

    def _observation(self) -> np.ndarray:
        fill_observation(self._batch.S, self._batch.P, self._X, self._V, self._A, self._ref_id,
                         self._k, self._offsets, self._prev_action, self._scales, self._obs)
        return self._obs.astype(np.float32)

    def close_extras(self, **kwargs: Any) -> None:
        pass

