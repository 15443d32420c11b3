"""``ServoAxisVectorEnv``: N single-axis envs stepped together by the batched kernel."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from fricbench._memory import check_memory, format_bytes
from fricbench._validation import check_int
from fricbench.axis import Axis, AxisBatch
from fricbench.axis import kernel as K
from fricbench.axis.batch import SimulationDivergedError
from fricbench.gym.task import (
    REFERENCE_BYTES_PER_SAMPLE,
    TaskConfig,
    action_array,
    fill_observation,
    n_features,
    obs_scales,
    preview_offsets,
    reference_for,
    stack_references,
)
from fricbench.gym.vector_step import (
    N_TABLE_FEATURES,
    reference_features,
    vector_step_rows,
    vector_step_shared,
)

__all__ = ["AXIS_OBJECT_BYTES", "ServoAxisVectorEnv", "bytes_per_env"]


AXIS_OBJECT_BYTES = 400
"""Estimated bytes of one :class:`~fricbench.axis.Axis` with its friction model (a sub-env holds
its own when friction is redrawn per episode)."""


def bytes_per_env(n_features: int, randomized: bool) -> int:
    """Estimated peak bytes per sub-env of :class:`ServoAxisVectorEnv` (within about 30 %).

    The batch's parameter and state rows, status and outputs; the env's indices, observation;
    the copies made at reset and the arrays returned by a step (the kernel's scratch is one
    sub-env's, whatever their number); one
    :class:`~fricbench.axis.Axis` per sub-env when friction is randomised.
    """
    batch = 8 * (K.N_PARAMS + K.N_STATE + 1 + 4 + 1)
    env = 8 * (3 + n_features + 1) + 1
    transient = 8 * (K.N_PARAMS + K.N_STATE + 6) + 2 * 4 * n_features + 2
    return batch + env + transient + (AXIS_OBJECT_BYTES if randomized else 0)


MAX_NUM_ENVS = 2**20
"""Most sub-envs of one vector env (about 1.6 GB)."""


class ServoAxisVectorEnv(VectorEnv):
    """A native vector version of :class:`~fricbench.gym.env.ServoAxisEnv` (single axis).

    All sub-envs share one :class:`~fricbench.axis.AxisBatch`, and a step is one compiled call
    (:func:`~fricbench.gym.vector_step.vector_step`) over every sub-env: action check and
    clipping, reference look-up, the axis kernel, observation, reward and truncation.
    References come from a pool generated at construction (``reference_pool`` per seeded
    trajectory choice, e.g. ``random``), and each sub-env draws from the pool at reset.
    Observations, actions and rewards are those of the scalar env. Autoreset follows
    Gymnasium's ``NEXT_STEP`` mode by default; in ``SAME_STEP`` mode (what stable-baselines3
    expects, :mod:`fricbench.gym.sb3`) a sub-env that truncates is reset within the same step:
    the step returns its reset observation, and ``info["final_obs"]`` (an object array, ``None``
    for the sub-envs that go on) holds the last observation of the finished episode, with the
    mask ``info["_final_obs"]`` (and an empty ``final_info``, masked alike). Actions have shape
    ``(num_envs, 1)`` (or ``(num_envs,)``) and are real numbers; ``step`` before ``reset``
    raises ``RuntimeError``.

    Parameters
    ----------
    num_envs : int
        Number of sub-envs, at most :data:`MAX_NUM_ENVS`.
    axis : Axis
    task : TaskConfig
    reference_pool : int
        References generated per seeded trajectory choice.
    seed : int
        Seed of the reference pool, and of the generator of the per-episode draws (reference
        choice, randomised parameters, noise) until ``reset(seed=...)`` replaces it.
    autoreset_mode : AutoresetMode or str
        ``AutoresetMode.NEXT_STEP`` (default) or ``AutoresetMode.SAME_STEP`` (or their values,
        ``"NextStep"``, ``"SameStep"``).

    Raises
    ------
    ValueError
        Also when ``num_envs`` or ``reference_pool`` would need more memory than is available
        (:func:`bytes_per_env`, :data:`~fricbench.gym.task.REFERENCE_BYTES_PER_SAMPLE`), before
        anything is allocated.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, axis: Axis | None = None,
                 task: TaskConfig | None = None, reference_pool: int = 4, seed: int = 0,
                 render_mode: str | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP) -> None:
        num_envs = check_int("num_envs", num_envs, 1)
        modes = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
        if autoreset_mode not in modes and autoreset_mode not in [m.value for m in modes]:
            raise ValueError(f"autoreset_mode={autoreset_mode!r}: expected one of "
                             f"{', '.join(str(m) for m in modes)} (or their values)")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        reference_pool = check_int("reference_pool", reference_pool, 1)
        seed = check_int("seed", seed, 0)
        if render_mode is not None:
            raise ValueError("render_mode: the vector env does not render; use ServoAxisEnv")
        self.axis = Axis() if axis is None else axis
        self.task = TaskConfig() if task is None else task
        if not isinstance(self.axis, Axis):
            raise TypeError(f"axis={axis!r}: expected an Axis")
        if not isinstance(self.task, TaskConfig):
            raise TypeError(f"task={task!r}: expected a TaskConfig")
        self.num_envs = num_envs
        self.ts = self.axis.controller.ts
        cfg = self.task.observation
        self._offsets = preview_offsets(cfg).astype(np.int64)
        self._scales = obs_scales(cfg)
        self._inv_scales = 1.0 / self._scales
        self._nf = n_features(cfg)
        # refuse what cannot fit before allocating or generating anything
        per_env = bytes_per_env(self._nf, bool(self.task.randomize.ranges))
        check_memory(f"num_envs={num_envs}", num_envs * per_env,
                     f"about {format_bytes(per_env)} per sub-env",
                     lambda room: f"num_envs <= {room // per_env} here")
        if num_envs > MAX_NUM_ENVS:
            # beyond it the construction's temporaries outgrow the estimate, and a 2-core
            # machine steps a million envs at a few steps per second
            raise ValueError(f"num_envs={num_envs}: expected at most {MAX_NUM_ENVS} "
                             "(MAX_NUM_ENVS); run several vector envs for more")
        pool_rng = np.random.default_rng(seed)
        refs = []
        envs = num_envs * per_env
        for choice in self.task.trajectories:
            count = reference_pool if choice.seeded else 1
            refs.append(reference_for(choice, self.ts, pool_rng))
            if count > 1:  # the seeded choices' references all have the first one's length
                per_ref = refs[-1].n_samples * REFERENCE_BYTES_PER_SAMPLE

                def pool_fix(room: int, per_ref: int = per_ref) -> str:
                    return f"reference_pool <= {max(room - envs, 0) // per_ref} here"

                check_memory(f"reference_pool={reference_pool}", count * per_ref + envs,
                             f"{count} references of {refs[-1].n_samples} samples, "
                             f"{REFERENCE_BYTES_PER_SAMPLE} B each, besides {num_envs} "
                             "sub-envs", pool_fix)
            refs.extend(reference_for(choice, self.ts, pool_rng) for _ in range(count - 1))
        if any(r.n_axes != 1 for r in refs):
            raise ValueError("ServoAxisVectorEnv drives single-axis references only")
        pad = int(self._offsets[-1]) if self._offsets.size else 0
        self._X, self._V, self._A, self._len = stack_references(refs, pad)
        # the step copies the scaled reference features from this table (vector_step)
        self._F = reference_features(self._X, self._V, self._A, self._inv_scales)
        self._preview = (N_TABLE_FEATURES * self._offsets).astype(np.uint64)
        self._names = [r.name for r in refs]
        self.single_observation_space = spaces.Box(-np.inf, np.inf, (self._nf,), np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._batch = AxisBatch(self.axis, n=num_envs)
        n = num_envs
        self._ref_id = np.zeros(n, dtype=np.int64)
        self._k = np.zeros(n, dtype=np.int64)
        self._prev_action = np.zeros(n)
        self._obs = np.zeros((n, self._nf))
        self._autoreset = np.zeros(n, dtype=bool)
        self._work = np.zeros((10, 1, 1))
        self._no_noise = np.zeros(n)
        # one generator for every draw; Gymnasium's ``np_random`` property shows the same one
        self._rng = self._np_random = np.random.default_rng(seed)
        self._needs_reset = True
        # actions of the action space's shape (N, 1), or (N,); checked before the compiled step
        self._action_shapes = ((num_envs, 1), (num_envs,))

    def _reset_rows(self, rows: np.ndarray) -> None:
        idx = np.flatnonzero(rows)
        if idx.size == 0:
            return
        rng = self._rng
        self._ref_id[idx] = rng.integers(0, self._X.shape[0], idx.size)
        self._k[idx] = 0
        self._prev_action[idx] = 0.0
        if self.task.randomize.ranges:
            for i in idx:
                self._batch.set_params(int(i), self.task.randomize.sample(self.axis, rng))
        noise = rng.standard_normal(idx.size) if self.axis.needs_noise else None
        self._batch.reset(self._X[self._ref_id[idx], 0], self._V[self._ref_id[idx], 0], noise,
                          rows=idx)

    @property
    def _shared_plant(self) -> bool:
        return self._batch.uniform

    def reset(self, *, seed: int | list[int] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        if isinstance(seed, list):
            seed = seed[0] if seed else None
        if seed is not None:
            seed = check_int("seed", seed, 0)
        if options is not None and not isinstance(options, Mapping):
            raise TypeError(f"options={options!r} ({type(options).__name__}): expected None; "
                            "the vector env takes no reset options")
        if options:
            raise ValueError(f"reset options {sorted(options, key=repr)}: the vector env takes "
                             "none")
        if seed is not None:
            self._rng = self._np_random = np.random.default_rng(seed)
        self._reset_rows(np.ones(self.num_envs, dtype=bool))
        self._autoreset[:] = False
        self._needs_reset = False
        return self._observation(), {}

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                 dict[str, Any]]:
        if self._needs_reset:
            raise RuntimeError("call reset() before step()")
        shape = self._action_shapes
        if type(actions) is np.ndarray and actions.dtype.kind == "f" and actions.shape in shape:
            a = actions.astype(np.float64, copy=False).reshape(self.num_envs)
        else:
            # finiteness and clipping are the compiled step's (it skips the held rows)
            a = action_array(actions, shape[0], "actions", also=shape[1:]).reshape(self.num_envs)
        hold = self._autoreset
        # count_nonzero: a quarter of what any() costs on 4096 booleans (about 2 us a step)
        if np.count_nonzero(hold):
            self._reset_rows(hold)
        draws = self._rng.standard_normal(self.num_envs) if self.axis.needs_noise \
            else self._no_noise
        obs = np.empty((self.num_envs, self._nf), dtype=np.float32)
        rewards = np.empty(self.num_envs)
        truncated = np.empty(self.num_envs, dtype=bool)
        reward = self.task.reward
        # while every row holds the same plant (no friction redrawn, no plant set per row)
        # the compiled step unpacks it once per step instead of once per sub-env
        step = vector_step_shared if self._shared_plant else vector_step_rows
        code = step(self._batch.P, self._batch.S, self._X, self._V, self._A, self._F,
                    self._len, self._ref_id, self._k, a, hold, self.task.action == "force",
                    self.task.action_scale, draws, self._preview, self._scales,
                    self._inv_scales, reward.error_scale, reward.action_weight,
                    self._prev_action, self._work, self._batch.status, obs, rewards, truncated)
        if code < 0:
            raise ValueError(f"actions[{-1 - code}] = {a[-1 - code]!r}: contains NaN or inf")
        if code > 0:
            self._raise_diverged(code - 1)
        info: dict[str, Any] = {}
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self._autoreset = truncated.copy()
        elif np.count_nonzero(truncated):
            info = self._reset_finished(obs, truncated)
        return obs, rewards, np.zeros(self.num_envs, dtype=bool), truncated, info

    def _reset_finished(self, obs: np.ndarray, done: np.ndarray) -> dict[str, Any]:
        """``SAME_STEP`` autoreset: reset the ``done`` rows and put their reset observation
        into ``obs``; return the info holding their final observation."""
        idx = np.flatnonzero(done)
        final = np.full(self.num_envs, None, dtype=object)
        for i in idx:
            final[i] = obs[i].copy()
        self._reset_rows(done)
        fresh = np.empty((idx.size, self._nf))
        fill_observation(self._batch.S[idx], self._batch.P[idx], self._X, self._V, self._A,
                         self._ref_id[idx], self._k[idx], self._offsets, self._prev_action[idx],
                         self._scales, fresh)
        obs[idx] = fresh
        return {"final_obs": final, "_final_obs": done.copy(), "final_info": {},
                "_final_info": done.copy()}

    def _raise_diverged(self, row: int) -> None:
        # re-run the failing row through AxisBatch.run, which raises with time, state and cause
        b = self._batch
        one = AxisBatch(b.axes[row])
        one.S[:] = b.S[row]
        one.status[:] = b.status[row]
        try:
            one.run(np.zeros((1, 0)), np.zeros((1, 0)), np.zeros((1, 0)))
        except SimulationDivergedError as exc:
            raise SimulationDivergedError(f"sub-env {row}: {exc}") from None
        raise SimulationDivergedError(f"sub-env {row}: diverged (status {b.status[row]})")

    def _observation(self) -> np.ndarray:
        fill_observation(self._batch.S, self._batch.P, self._X, self._V, self._A, self._ref_id,
                         self._k, self._offsets, self._prev_action, self._scales, self._obs)
        return self._obs.astype(np.float32)

    def close_extras(self, **kwargs: Any) -> None:
        pass

