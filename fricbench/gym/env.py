"""``ServoAxisEnv``: a servo feed axis (or D coordinated axes) with friction, as a Gymnasium env."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from fricbench.axis import Axis, AxisBatch
from fricbench.axis import kernel as K
from fricbench.gym.task import (
    TaskConfig,
    TrajectoryChoice,
    apply_action,
    check_action,
    fill_observation,
    n_features,
    obs_scales,
    preview_offsets,
    reference_for,
)
from fricbench.trajectories import Reference

__all__ = ["ServoAxisEnv"]


if TYPE_CHECKING:
    from fricbench.compensators.base import EpisodeContext
    from fricbench.gym.render import AxisFigure, EpisodeTrace


class ServoAxisEnv(gym.Env[np.ndarray, np.ndarray]):
    """## Description

    A CNC feed axis in position mode (position P with velocity feedforward, velocity PI, current
    gain with saturation, rigid mechanics with nonlinear friction and optional effects) follows a
    reference trajectory. The agent adds a compensation to the loop each control sample (1 ms by
    default) to cut the tracking error that friction causes at starts, stops and reversals.
    With a two-axis reference (``circle``) the env drives X and Y together and the measure is the
    contour error.

    ## Action Space

    ``Box(-1, 1, (D,), float32)``, one entry per axis. ``task.action == "force"``: compensation
    force ``a * action_scale`` N added to the velocity-loop output (default 600 N per unit, above
    the default breakaway force of 500 N). ``task.action == "offset"``: reference offset
    ``a * action_scale`` m (pre-compensation). Out-of-range actions are clipped to [-1, 1];
    NaN or inf, or a shape other than ``(D,)`` (a plain number for ``D = 1``), raise
    ``ValueError``; values that are not real numbers (strings, complex, bool) ``TypeError``.

    ## Observation Space

    ``Box(-inf, inf, (D * F [+ 1],), float32)`` with ``F = 7 + 2 * preview`` features per axis,
    each divided by its scale so that it is O(1): measured tracking error / ``error_scale``
    (10 um), reference position / 0.1 m, reference velocity / 0.05 m/s, reference acceleration /
    1 m/s^2, measured velocity / 0.05 m/s, previous action, motor force of the last sample /
    1000 N (drives report their current), then ``preview`` future reference
    velocities and accelerations every ``preview_stride`` samples (the look-ahead a CNC has).
    Two-axis envs append the contour error / ``error_scale``.

    ## Rewards

    ``r = -(e / reward.error_scale)^2 - reward.action_weight * |a|^2`` with ``e`` the measured
    tracking error (contour error for two axes). ``info`` carries ``error_m`` (true tracking
    error, m), ``measured_error_m``, ``reward_error``, ``reward_action``, ``force_N`` and
    ``contour_error_m`` for two axes.

    ## Starting State

    At rest on the first reference sample; a trajectory drawn from ``task.trajectories`` with
    the env's seeded generator, or given by ``reset(options={"trajectory": ...})`` (an id, a
    ``{"id": ..., **params}`` table, or a :class:`~fricbench.trajectories.Reference`). Friction
    parameters are redrawn per episode when ``task.randomize`` is set.

    ## Episode End

    Truncation at the last sample of the trajectory; no termination. An axis whose sampled
    linear loop is unstable is refused when it is built (``ValueError``); a simulation that
    still diverges raises :class:`~fricbench.axis.SimulationDivergedError`.

    ## Arguments

    ``ServoAxisEnv(axis, task, render_mode, plant)``: ``axis`` (:class:`~fricbench.axis.Axis`,
    the nominal axis that compensators are told of), ``task``
    (:class:`~fricbench.gym.task.TaskConfig`), ``render_mode`` (``"rgb_array"`` or
    ``"human"``; see :meth:`render`: position, error, velocity and the friction law with the
    operating point; ``"human"`` draws ``metadata["render_fps"]`` (25) frames per second of
    simulated time and warns once, drawing off-screen, where there is no display), ``plant``
    (an :class:`~fricbench.axis.Axis` simulated in place of ``axis``, such as one the benchmark
    draws per seed around the nominal: :func:`fricbench.axis.variation.draw_plant`; ``None``: the
    nominal axis itself). With ``effects.current_noise_std > 0`` the motor force of the
    observation carries the current-measurement noise.

    Registered ids are built from the TOML specs in ``envs/``, and the keywords of
    ``gymnasium.make`` (and ``make_vec``) are merged onto the env's spec, checked as a spec file
    is (:func:`fricbench.gym.make_env`)::

        gym.make("fricbench/PaperAxisShifted-v0", friction="lugre")   # keeps fc, fs, vs
        gym.make("fricbench/PaperAxis-v0", fc=400.0)                  # friction={"fc": 400.0}
        gym.make("fricbench/PaperAxis-v0", effects={"noise_std": 1e-7},
                 trajectories=["s_curve", {"id": "curve", "duration": 5.0}])

    * ``controller``, ``mechanics``, ``effects`` (the axis), ``observation``, ``reward`` (the
      task): dicts merged key by key onto that table of the spec.
    * ``friction``: a friction model id (a new model keeps the parameters it shares with the
      spec's, the others take their defaults) or a dict merged onto the spec's friction table
      (may hold an ``"id"``).
    * ``trajectories`` (replaces the set), ``action``, ``action_scale``, ``randomize`` (dict of
      ``[low, high]`` ranges merged onto the spec's).
    * Any key of these tables on its own (``fc=400.0``, ``kp=200.0``) when one table has it.
    * A key given as ``None`` takes its default instead of the spec's value.
    * ``axis`` / ``task``: an :class:`~fricbench.axis.Axis` / :class:`TaskConfig` used in place
      of the spec's, only if it agrees with every setting the spec file writes; otherwise
      :class:`~fricbench.gym.EnvKeywordError` lists what differs (pass the changes as
      keywords, or construct ``ServoAxisEnv`` yourself).

    Unknown keywords (with "did you mean"), wrong types and out-of-range values raise
    :class:`~fricbench.gym.EnvKeywordError` (a ``ValueError``) naming the key, the value and
    what was expected. An empty override (``friction={}``) is the env as registered.

    ## Version History

    * v0: initial version; ``gym.make`` keywords merged onto the spec (they used to be
      refused, and ``axis=`` replaced the spec's axis whole).
      ``render_fps`` 25 (was 10, and human mode drew every step); the frame has four panels.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 25}

    def __init__(self, axis: Axis | None = None, task: TaskConfig | None = None,
                 render_mode: str | None = None, plant: Axis | None = None) -> None:
        self.axis = Axis() if axis is None else axis
        self.task = TaskConfig() if task is None else task
        if not isinstance(self.axis, Axis):
            raise TypeError(f"axis={axis!r}: expected an Axis")
        if plant is not None and not isinstance(plant, Axis):
            raise TypeError(f"plant={plant!r}: expected an Axis or None")
        if plant is not None and plant.controller != self.axis.controller:
            raise ValueError("plant: its controller differs from the nominal axis's (a plant "
                             "varies the machine, not the controller settings)")
        self.plant = self.axis if plant is None else plant
        if not isinstance(self.task, TaskConfig):
            raise TypeError(f"task={task!r}: expected a TaskConfig")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r}: expected one of "
                             f"{self.metadata['render_modes']} or None")
        self.render_mode = render_mode
        self.ts = self.axis.controller.ts
        probe = reference_for(self.task.trajectories[0], self.ts, np.random.default_rng(0))
        self.n_axes = probe.n_axes
        for choice in self.task.trajectories[1:]:
            d = reference_for(choice, self.ts, np.random.default_rng(0)).n_axes
            if d != self.n_axes:
                raise ValueError(f"task.trajectories mixes {self.n_axes}- and {d}-axis references")
        self._nf = n_features(self.task.observation)
        obs_dim = self.n_axes * self._nf + (1 if self.n_axes == 2 else 0)
        self.observation_space = spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.n_axes,), np.float32)
        self._batch = AxisBatch(self.axis, n=self.n_axes)
        self._offsets = preview_offsets(self.task.observation).astype(np.int64)
        d = self.n_axes
        self._obs_rows = np.zeros((d, self._nf))
        self._scales = obs_scales(self.task.observation)
        self._rows = np.arange(d, dtype=np.int64)
        self._kvec = np.zeros(d, dtype=np.int64)
        self._out = (np.empty((d, 1)), np.empty((d, 1)), np.empty((d, 1)), np.empty((d, 1)))
        self._act = np.zeros(d)
        self._u_force = np.zeros((d, 1))
        self._u_off = np.zeros((d, 1))
        self._noise = np.zeros((d, 1))
        self._prev_action = np.zeros(d)
        self.reference: Reference | None = None
        self._k = 0
        self._trace: EpisodeTrace | None = None
        self._fig: AxisFigure | None = None
        self._frame_slot = -1
        self._warned_headless = False

    # -- episode ------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        if options is not None and not isinstance(options, Mapping):
            raise TypeError(f"options={options!r} ({type(options).__name__}): expected a dict "
                            "such as {'trajectory': 'curve'}, or None")
        super().reset(seed=seed)
        options = options or {}
        unknown = set(options) - {"trajectory"}
        if unknown:
            raise ValueError(f"reset options: unknown keys {sorted(unknown, key=repr)}; "
                             "expected 'trajectory'")
        traj = options.get("trajectory")
        rng = self.np_random
        if traj is None:
            choice = self.task.trajectories[int(rng.integers(len(self.task.trajectories)))]
            ref = reference_for(choice, self.ts, rng)
        elif isinstance(traj, Reference):
            ref = traj
        else:
            ref = reference_for(TrajectoryChoice.parse(traj), self.ts, rng)
        if ref.n_axes != self.n_axes:
            raise ValueError(f"trajectory {ref.name!r} has {ref.n_axes} axes; this env drives "
                             f"{self.n_axes}")
        if abs(ref.ts - self.ts) > 1e-12:
            raise ValueError(f"trajectory sampled at ts={ref.ts:g} s; the axis runs at "
                             f"{self.ts:g} s")
        self.reference = ref
        axis = self.task.randomize.sample(self.plant, rng)
        for i in range(self.n_axes):
            self._batch.set_params(i, axis)
        self.current_axis = axis
        pad = int(self._offsets[-1]) if self._offsets.size else 0
        k_total = ref.n_samples
        idx = np.minimum(np.arange(k_total + pad), k_total - 1)
        rows = (lambda z: np.atleast_2d(z)[:, idx])
        self._xr, self._vr, self._ar = rows(ref.x), rows(ref.v), rows(ref.a)
        self._vr[:, k_total:] = 0.0
        self._ar[:, k_total:] = 0.0
        self._k = 0
        self._prev_action[:] = 0.0
        self._u_force[:] = 0.0
        self._u_off[:] = 0.0
        d = self.n_axes
        noise0 = rng.standard_normal(d) if self.plant.needs_noise else np.zeros(d)
        self._batch.reset(self._xr[:, 0], self._vr[:, 0], noise0)
        if self.render_mode is not None:
            from fricbench.gym.render import EpisodeTrace

            self._trace = EpisodeTrace.start(ref.t, self._xr[:, :k_total], self._vr[:, :k_total],
                                             axis.friction)
            self._frame_slot = -1
            self._record(np.zeros(d))
            if self.render_mode == "human":
                self._human_frame(final=False)
        return self._observation(), {"trajectory": ref.name, "friction": axis.friction.to_dict()}

    @property
    def true_position(self) -> np.ndarray:
        """True table position of each axis at the current sample, m, shape (D,)."""
        return self._batch.true_position.copy()

    def episode_context(self, *, rehearsal: bool = True) -> EpisodeContext:
        """What a compensator is told about the episode :meth:`reset` started.

        Parameters
        ----------
        rehearsal : bool
            Offer ``rehearse(u, seed)``: the episode's reference run on the episode's axis
            with a feedforward ``u`` (for iterative learning before the scored run).

        Returns
        -------
        EpisodeContext
            The whole reference, the nominal axis (not the episode's randomised friction),
            the task, and the rehearsal.
        """
        from fricbench.axis import SimulationResult, simulate
        from fricbench.compensators.base import EpisodeContext

        ref = self.reference
        if ref is None:
            raise RuntimeError("call reset() before episode_context()")
        axis, mode = self.current_axis, self.task.action

        def rehearse(u: np.ndarray, seed: int) -> SimulationResult:
            """Run the episode's reference on the episode's axis with feedforward ``u``."""
            if mode == "force":
                return simulate(axis, ref, seed=seed, u_force=u)
            return simulate(axis, ref, seed=seed, u_offset=u)

        return EpisodeContext(reference=ref, nominal_axis=self.axis, task=self.task,
                              rehearse=rehearse if rehearsal else None)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, SupportsFloat, bool, bool,
                                                 dict[str, Any]]:
        if self.reference is None:
            raise RuntimeError("call reset() before step()")
        if self._k >= self.reference.n_samples - 1:
            raise RuntimeError("episode is over (truncated): call reset()")
        a = self._act
        if type(action) is np.ndarray and action.shape == a.shape and action.dtype.kind == "f":
            a[:] = action
        else:
            # anything else is checked: real numbers of shape (D,) (a plain number for D = 1)
            a = check_action(action, a.shape, also=((),) if self.n_axes == 1 else ())
        target = self._u_force if self.task.action == "force" else self._u_off
        if not apply_action(a, self.task.action_scale, target):
            raise ValueError(f"action={np.asarray(action)!r}: contains NaN or inf")
        k = self._k
        if self.plant.needs_noise:
            self._noise[:, 0] = self.np_random.standard_normal(self.n_axes)
        b = self._batch
        sl = slice(k, k + 1)
        K.run_kernel(b.P, b.S, self._xr[:, sl], self._vr[:, sl], self._ar[:, sl],
                     self._u_force, self._u_off, self._noise, self._out, b.status)
        if b.status[0] or (self.n_axes > 1 and b.status.any()):
            b.run(self._xr[:, sl], self._vr[:, sl], self._ar[:, sl])  # raises with the cause
        self._k = k + 1
        self._prev_action[:] = a
        obs = self._observation()
        err_meas = self._obs_rows[:, 0] * self.task.observation.error_scale
        err_true = self._xr[:, k + 1] - b.true_position
        info: dict[str, Any] = {"measured_error_m": err_meas.copy(), "error_m": err_true,
                                "force_N": self._out[2][:, 0].copy()}
        if self.n_axes == 2:
            scored = self._contour_error(err_meas, k + 1)
            info["contour_error_m"] = self._contour_error(err_true, k + 1)
        else:
            scored = float(err_meas[0])
        r_err = -(scored / self.task.reward.error_scale) ** 2
        r_act = -self.task.reward.action_weight * float(a @ a)
        info["reward_error"] = r_err
        info["reward_action"] = r_act
        truncated = self._k >= self.reference.n_samples - 1
        if self.render_mode is not None:
            self._record(self._out[3][:, 0])
            if self.render_mode == "human":
                self._human_frame(final=truncated)
        return obs, r_err + r_act, False, truncated, info

    def run_actions(self, actions: np.ndarray) -> np.ndarray:
        """Step the episode with a precomputed action sequence in one kernel call.

        The same numbers as ``step`` called with each column in turn (the env's generator
        draws the same noise in the same order), without building observations, rewards or
        render frames: for compensators whose actions do not depend on the observation.

        Parameters
        ----------
        actions : ndarray, shape (D, n)
            Actions in [-1, 1] (clipped as ``step`` does), one column per step.

        Returns
        -------
        ndarray, shape (D, n)
            True tracking error after each step, m (``info["error_m"]`` of ``step``).
        """
        ref = self.reference
        if ref is None:
            raise RuntimeError("call reset() before run_actions()")
        a = np.asarray(actions, dtype=np.float64)
        d, k = self.n_axes, self._k
        if a.ndim != 2 or a.shape[0] != d:
            raise ValueError(f"actions has shape {a.shape}: expected ({d}, n)")
        n = a.shape[1]
        if n < 1 or k + n > ref.n_samples - 1:
            raise ValueError(f"actions: {n} steps from sample {k}; the episode has "
                             f"{ref.n_samples - 1 - k} left")
        if not np.isfinite(a).all():
            raise ValueError("actions: contains NaN or inf")
        a = np.clip(a, -1.0, 1.0)
        u = a * self.task.action_scale
        zeros = np.zeros((d, n))
        rng = self.np_random
        i_std = self.plant.effects.current_noise_std
        # step draws the encoder noise before the kernel, the current noise after it
        if self.plant.needs_noise and i_std > 0.0:
            noise = np.ascontiguousarray(rng.standard_normal((n, 2, d))[:, 0, :].T)
        elif self.plant.needs_noise:
            noise = np.ascontiguousarray(rng.standard_normal((n, d)).T)
        else:
            noise = zeros
            if i_std > 0.0:
                rng.standard_normal((n, d))
        sl = slice(k, k + n)
        force = self.task.action == "force"
        x_true = self._batch.run(self._xr[:, sl], self._vr[:, sl], self._ar[:, sl],
                                 u if force else zeros, zeros if force else u, noise)[0]
        self._k = k + n
        self._prev_action[:] = a[:, -1]
        # out[0] holds the position at the start of each sample: shift by one
        after = np.concatenate([x_true[:, 1:], self._batch.true_position[:, None]], axis=1)
        return self._xr[:, k + 1:k + n + 1] - after

    # -- observation --------------------------------------------------------------------------
    def _contour_error(self, err: np.ndarray, k: int) -> float:
        """Error component normal to the reference path (ISO 230-4 radial deviation on a
        circle), m."""
        vx, vy = self._vr[0, k], self._vr[1, k]
        speed = float(np.hypot(vx, vy))
        if speed < 1e-9:
            return float(np.hypot(err[0], err[1]))
        # e_c = e x t: component of the error normal to the tangent t = v / |v|
        return float((err[0] * vy - err[1] * vx) / speed)

    def _observation(self) -> np.ndarray:
        self._kvec[:] = self._k
        fill_observation(self._batch.S, self._batch.P, self._xr, self._vr, self._ar, self._rows,
                         self._kvec, self._offsets, self._prev_action, self._scales,
                         self._obs_rows)
        i_std = self.plant.effects.current_noise_std
        if i_std > 0.0:
            # F_meas = kt (i + n_i): the drive reports a noisy current
            self._obs_rows[:, 6] += (self.plant.controller.kt * i_std
                                     / self.task.observation.force_scale
                                     * self.np_random.standard_normal(self.n_axes))
        if self.n_axes == 2:
            err = self._obs_rows[:, 0] * self.task.observation.error_scale
            ec = self._contour_error(err, self._k) / self.task.observation.error_scale
            return np.append(self._obs_rows.ravel(), ec).astype(np.float32)
        return self._obs_rows.ravel().astype(np.float32)

    # -- rendering ----------------------------------------------------------------------------
    def _record(self, friction: np.ndarray) -> None:
        """Store the current sample in the episode's trace (only with a render_mode)."""
        if self._trace is None:
            return
        k = self._k
        b = self._batch
        self._trace.record(k, b.position, self._xr[:, k] - b.true_position, b.velocity, friction)

    def _human_frame(self, final: bool) -> None:
        """Draw a frame when the simulated time enters a new 1 / render_fps slot, and at the end.

        Frames follow simulated time: at ``t = 0``, at the first sample of each later slot
        ``[m / fps, (m + 1) / fps)``, and at the last sample of the episode; the steps in
        between are not drawn (the traces still show every sample).
        """
        fps = float(self.metadata["render_fps"])
        # m = floor(t_k fps): the slot of sample k (1e-9 keeps t = m / fps in slot m)
        slot = int(np.floor(self._k * self.ts * fps + 1e-9))
        if slot > self._frame_slot or final:
            self._frame_slot = slot
            self.render()

    def render(self) -> np.ndarray | None:
        """The episode so far as a picture: reference and actual position, tracking error and
        velocity against time with a time cursor, and the friction force against velocity (the
        friction model's steady-state curve with the operating point on it).

        ``render_mode="rgb_array"``: returns an (H, W, 3) uint8 frame, each call (under 20 ms a
        frame; ``python -m fricbench.gym.render_benchmark``). ``"human"``: :meth:`reset` and
        :meth:`step` draw into a window ``metadata["render_fps"]`` times per second of
        simulated time (not every step); without a display it warns once and draws off-screen.
        """
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode; pass render_mode='rgb_array'")
            return None
        if self._trace is None:
            raise RuntimeError("call reset() before render()")
        if self._fig is None:
            from fricbench.gym.render import AxisFigure, display_available, warn_headless

            window = False
            if self.render_mode == "human":
                window, backend = display_available()
                if not window and not self._warned_headless:
                    self._warned_headless = True
                    warn_headless(backend)
            self._fig = AxisFigure(window=window)
        frame = self._fig.draw(self._trace)
        return frame if self.render_mode == "rgb_array" else None

    def close(self) -> None:
        if self._fig is not None:
            self._fig.close()
            self._fig = None
