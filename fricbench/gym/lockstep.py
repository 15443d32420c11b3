"""``LockstepEnvs``: scalar envs stepped together, one kernel call per sample over all their axes.

The benchmark scores a compensator on the seeds of a cell: one :class:`~fricbench.gym.env.
ServoAxisEnv` per seed, each on its own plant with its own noise generator, all on the same
trajectory. Stepped one by one, the Python around each kernel call (action check, observation,
info) costs more than the physics. ``LockstepEnvs`` takes the envs after their ``reset`` and
steps them as one batch: their axes stacked into one :class:`~fricbench.axis.AxisBatch`, one
:func:`~fricbench.axis.kernel.run_kernel` call and one observation fill per sample, each env's
noise still drawn from its own generator in the order its ``step`` draws it. Every row gets
exactly, bit for bit, the numbers its env's ``step`` would give (the tests compare them on every
benchmark env), so a cell run in lockstep is the same as its seeds run one after another.

It is not a Gymnasium vector env (no autoreset, no spaces of its own, every row ends on the same
sample); :class:`~fricbench.gym.vector.ServoAxisVectorEnv` is the one for training.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fricbench.axis import AxisBatch
from fricbench.axis import kernel as K
from fricbench.gym.env import ServoAxisEnv
from fricbench.gym.task import apply_action, fill_observation

__all__ = ["LockstepEnvs"]


class LockstepEnvs:
    """``N`` reset :class:`~fricbench.gym.env.ServoAxisEnv` stepped together.

    Parameters
    ----------
    envs : sequence of ServoAxisEnv
        Envs after ``reset``, none stepped yet; one task (observation layout, action mode and
        scale), one number of axes and references of one length. Their generators and states
        are used in place: after :meth:`close` (or the last step) each env holds the state and
        sample index its own steps would have left.

    Raises
    ------
    ValueError
        An empty list, an env not reset or already stepped, or envs that differ in task,
        number of axes or reference length.
    """

    def __init__(self, envs: Sequence[ServoAxisEnv]) -> None:
        self.envs = list(envs)
        if not self.envs:
            raise ValueError("envs: expected at least one reset ServoAxisEnv")
        first = self.envs[0]
        for i, env in enumerate(self.envs):
            if not isinstance(env, ServoAxisEnv):
                raise TypeError(f"envs[{i}]={env!r}: expected a ServoAxisEnv")
            if env.reference is None or env._k != 0:
                raise ValueError(f"envs[{i}]: expected an env just reset (reset() called, not "
                                 "stepped)")
            if env.task != first.task or env.n_axes != first.n_axes:
                raise ValueError(f"envs[{i}]: its task or number of axes differs from envs[0]'s")
        lengths = [env.reference.n_samples for env in self.envs if env.reference is not None]
        if len(set(lengths)) > 1:
            i = next(j for j, n in enumerate(lengths) if n != lengths[0])
            raise ValueError(f"envs[{i}]: a reference of {lengths[i]} samples; envs[0]'s has "
                             f"{lengths[0]}")
        self.task = first.task
        self.n_envs = len(self.envs)
        self.n_axes = d = first.n_axes
        self.n_samples = lengths[0]
        rows = self.n_envs * d
        self._batch = AxisBatch([env.current_axis for env in self.envs for _ in range(d)])
        self._batch.S[:] = np.concatenate([env._batch.S for env in self.envs])
        self._xr = np.ascontiguousarray(np.concatenate([env._xr for env in self.envs]))
        self._vr = np.ascontiguousarray(np.concatenate([env._vr for env in self.envs]))
        self._ar = np.ascontiguousarray(np.concatenate([env._ar for env in self.envs]))
        self._rows = np.arange(rows, dtype=np.int64)
        self._kvec = np.zeros(rows, dtype=np.int64)
        self._offsets = first._offsets
        self._scales = first._scales
        self._nf = first._nf
        self._obs_rows = np.zeros((rows, self._nf))
        self._act = np.zeros(rows)
        self._u_force = np.zeros((rows, 1))
        self._u_off = np.zeros((rows, 1))
        self._noise = np.zeros((rows, 1))
        self._out = (np.empty((rows, 1)), np.empty((rows, 1)), np.empty((rows, 1)),
                     np.empty((rows, 1)))
        self._prev_action = np.zeros(rows)
        # per env: its generator, whether its plant draws encoder noise, and the scale of its
        # current-measurement noise in observation units (as ServoAxisEnv computes it)
        f_s = self.task.observation.force_scale
        rngs = [env.np_random for env in self.envs]
        # each env's draws go straight into its rows of one buffer (Generator.standard_normal
        # with out= gives the numbers of standard_normal(d)): encoder noise before the kernel,
        # the drive's current noise with the observation, as ServoAxisEnv.step draws them
        self._enc = np.zeros(rows)
        self._enc_draws = [(rng, self._enc[i * d:(i + 1) * d])
                           for i, (rng, env) in enumerate(zip(rngs, self.envs, strict=True))
                           if env.plant.needs_noise]
        self._cur = np.zeros(rows)
        self._cur_draws = [(rng, self._cur[i * d:(i + 1) * d])
                           for i, (rng, env) in enumerate(zip(rngs, self.envs, strict=True))
                           if env.plant.effects.current_noise_std > 0.0]
        noisy = [i * d + j for i, env in enumerate(self.envs)
                 if env.plant.effects.current_noise_std > 0.0 for j in range(d)]
        self._cur_rows: slice | np.ndarray = slice(None) if len(noisy) == rows \
            else np.array(noisy, dtype=np.int64)
        # F_meas = kt (i + n_i): the current noise in observation units, per row
        self._cur_scale = np.array([env.plant.controller.kt * env.plant.effects.current_noise_std
                                    / f_s for env in self.envs for _ in range(d)])[
            self._cur_rows]
        self._k = 0

    @property
    def done(self) -> bool:
        """Whether the episodes reached their last sample (truncation)."""
        return self._k >= self.n_samples - 1

    @property
    def true_position(self) -> np.ndarray:
        """True table position of each env's axes at the current sample, m, shape (N, D)."""
        return self._batch.true_position.reshape(self.n_envs, self.n_axes).copy()

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One sample of every env.

        Parameters
        ----------
        actions : ndarray, shape (N, D)
            Actions in [-1, 1] (clipped as ``ServoAxisEnv.step`` clips), real numbers.

        Returns
        -------
        obs : ndarray, shape (N, obs_dim), float32
            Each env's observation (``step``'s first return).
        error_m : ndarray, shape (N, D)
            True tracking error after the step, m (``info["error_m"]``).

        Raises
        ------
        ValueError
            Actions of another shape, or NaN/inf in them (naming the env).
        SimulationDivergedError
            When an env's simulation diverges (naming the env, as its ``step`` would).
        """
        if self.done:
            raise RuntimeError("episodes are over (truncated)")
        n, d = self.n_envs, self.n_axes
        a = np.asarray(actions)
        if a.shape != (n, d) or a.dtype.kind != "f":
            raise ValueError(f"actions: shape {a.shape}, dtype {a.dtype}; expected real numbers "
                             f"of shape ({n}, {d})")
        act = self._act
        act[:] = a.reshape(-1)
        target = self._u_force if self.task.action == "force" else self._u_off
        if not apply_action(act, self.task.action_scale, target):
            bad = int(np.flatnonzero(~np.isfinite(act))[0]) // d
            raise ValueError(f"actions[{bad}]={a[bad]!r}: contains NaN or inf")
        k = self._k
        if self._enc_draws:
            for rng, out in self._enc_draws:
                rng.standard_normal(out=out)
            self._noise[:, 0] = self._enc
        b = self._batch
        sl = slice(k, k + 1)
        K.run_kernel(b.P, b.S, self._xr[:, sl], self._vr[:, sl], self._ar[:, sl],
                     self._u_force, self._u_off, self._noise, self._out, b.status)
        if b.status.any():
            self._raise_diverged(sl)
        self._k = k + 1
        self._prev_action[:] = act
        obs = self._observation()
        err = self._xr[:, k + 1] - b.true_position
        return obs, err.reshape(n, d)

    def _raise_diverged(self, sl: slice) -> None:
        from fricbench.axis.batch import SimulationDivergedError

        row = int(np.flatnonzero(self._batch.status)[0])
        i, d = divmod(row, self.n_axes)
        one = AxisBatch(self._batch.axes[row])
        one.S[:] = self._batch.S[row]
        one.status[:] = self._batch.status[row]
        try:  # AxisBatch.run raises with the time, the state and the likely cause
            one.run(np.zeros((1, 0)), np.zeros((1, 0)), np.zeros((1, 0)))
        except SimulationDivergedError as exc:
            raise SimulationDivergedError(f"env {i}: {exc}") from None
        raise SimulationDivergedError(f"env {i}, axis {d}: diverged")

    def _observation(self) -> np.ndarray:
        n, d = self.n_envs, self.n_axes
        self._kvec[:] = self._k
        rows = self._obs_rows
        fill_observation(self._batch.S, self._batch.P, self._xr, self._vr, self._ar, self._rows,
                         self._kvec, self._offsets, self._prev_action, self._scales, rows)
        if self._cur_draws:
            for rng, out in self._cur_draws:
                rng.standard_normal(out=out)
            cur = self._cur_rows
            rows[cur, 6] += self._cur_scale * self._cur[cur]
        flat = rows.reshape(n, d * self._nf)
        if d == 2:
            e_s = self.task.observation.error_scale
            ec = np.array([env._contour_error(rows[2 * i:2 * i + 2, 0] * e_s, self._k) / e_s
                           for i, env in enumerate(self.envs)])
            return np.column_stack([flat, ec]).astype(np.float32)
        return flat.astype(np.float32)

    def close(self) -> None:
        """Write each row's state, sample index and last action back into its env."""
        d = self.n_axes
        for i, env in enumerate(self.envs):
            env._batch.S[:] = self._batch.S[i * d:(i + 1) * d]
            env._batch.status[:] = self._batch.status[i * d:(i + 1) * d]
            env._k = self._k
            env._prev_action[:] = self._prev_action[i * d:(i + 1) * d]
