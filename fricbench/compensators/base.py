"""The compensator API: one small interface for every compensation strategy.

A compensator acts in the env loop::

    comp = make_compensator("kalman").fit("fricbench/PaperAxis-v0", seed=0)
    obs, info = env.reset(seed=s, options={"trajectory": "m_serial"})
    comp.reset(env.episode_context(), seed=s)
    while not done:
        obs, reward, terminated, truncated, info = env.step(comp.act(obs))

What a compensator may know is what a CNC knows: the whole reference program (look-ahead), the
nominal axis parameters (identified at commissioning: ``context.nominal_axis``), the env's
observation and action conventions, and what it learned in :meth:`Compensator.fit` from the
env's *training* setup (never the evaluation runs). Iterative methods (ILC) may rehearse the
same reference on the machine before the scored run through ``context.rehearse``.
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from fricbench.axis import Axis, SimulationResult
from fricbench.exceptions import NotFittedError
from fricbench.gym.task import FEATURES, N_BASE_FEATURES, ObservationConfig, TaskConfig
from fricbench.trajectories import Reference

__all__ = [
    "CATEGORIES",
    "Compensator",
    "CompensatorBatch",
    "CompensatorError",
    "EpisodeContext",
    "NotFittedError",
    "feature_index",
]


CATEGORIES = ("trials", "model", "online", "policy")
"""What a compensator uses beyond the scored run (:attr:`Compensator.category`).

``trials``: rehearses the scored reference on the machine before it is scored (ILC);
``model``: fitted in :meth:`Compensator.fit` on training runs of the machine (predictors,
friction feedforward, pre-compensation); ``online``: learns nothing beforehand and adapts while
it runs (observers; ``none`` too, which uses nothing at all); ``policy``: learned offline on
other references and plants (RL). Leaderboards rank within each category and overall.
"""


class CompensatorError(RuntimeError):
    """A compensator failed (bad output, corrupt policy file, ...)."""


def feature_index(name: str, axis: int = 0, cfg: ObservationConfig | None = None) -> int:
    """Column of feature ``name`` (see ``fricbench.gym.task.FEATURES``) of coordinate ``axis``.

    Preview features are ``"preview_v"`` and ``"preview_a"`` (first preview point).
    """
    cfg = cfg or ObservationConfig()
    per_axis = N_BASE_FEATURES + 2 * cfg.preview
    if name in FEATURES:
        col = FEATURES.index(name)
    elif name == "preview_v":
        col = N_BASE_FEATURES
    elif name == "preview_a":
        col = N_BASE_FEATURES + cfg.preview
    else:
        known = (*FEATURES, "preview_v", "preview_a")
        raise ValueError(f"feature {name!r}: expected one of {known}")
    return axis * per_axis + col


@dataclass
class EpisodeContext:
    """What a compensator is told at the start of an episode.

    Attributes
    ----------
    reference : Reference
        The whole reference of the episode (a CNC knows its program ahead).
    nominal_axis : Axis
        Nominal (commissioning) parameters of the axis: controller, mass, damping; its friction
        entry is the env's nominal friction, *not* the episode's randomised one.
    task : TaskConfig
        Action mode and scale, observation scales.
    rehearse : callable or None
        ``rehearse(u, seed) -> SimulationResult``: run the same reference on the machine with the
        feedforward ``u`` (force in N or offset in m, shape (K,) or (D, K), per
        ``task.action``), for iterative learning before the scored run. ``None`` when the
        runner does not allow rehearsal.
    """

    reference: Reference
    nominal_axis: Axis
    task: TaskConfig
    rehearse: Callable[[np.ndarray, int], SimulationResult] | None = None
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def ts(self) -> float:
        """Control sample time, s."""
        return self.nominal_axis.controller.ts

    @property
    def n_axes(self) -> int:
        """Coordinated axes D."""
        return self.reference.n_axes


class Compensator(abc.ABC):
    """Base class: public ``act`` validates, subclasses write ``_act``.

    Class attributes
    ----------------
    id : str
        Registered id (the class's default; :func:`make_compensator` sets the id it was made
        by, so that keyword variants of one class, ``tf-precomp`` and ``greybox-precomp``,
        name themselves).
    action_mode : {"force", "offset"}
        The env action this compensator produces (force at the velocity-loop output, or a
        reference offset for pre-compensation).
    learns : bool
        Whether :meth:`fit` must be called before use.
    category : {"trials", "model", "online", "policy"}
        What it uses beyond the scored run (:data:`CATEGORIES`); every registered compensator
        declares one (the registry's conformance test checks it), and leaderboards rank within
        each.
    """

    id: str = ""
    action_mode: ClassVar[str] = "force"
    learns: ClassVar[bool] = False
    category: ClassVar[str] = ""

    def __init__(self) -> None:
        self._context: EpisodeContext | None = None
        self._fitted = not self.learns

    # -- learning -----------------------------------------------------------------------------
    def fit(self, env_id: str, *, seed: int = 0, axis: Axis | None = None) -> Compensator:
        """Learn from the training setup of ``env_id`` (its axis, training trajectories).

        ``axis`` is the machine the training runs are recorded on (the benchmark passes each
        seed's plant, :func:`fricbench.axis.variation.draw_plant`); ``None``: the env's nominal
        axis. Its parameters are not to be read as known: only its runs are.

        The default does nothing; learning compensators override it and set ``_fitted``.
        """
        self._fitted = True
        return self

    def check_setup(self, env_id: str) -> None:  # noqa: B027 - optional hook
        """Check, without learning, what :meth:`fit` on ``env_id`` will read: the files its
        constructor keywords name (a policy) and that they suit ``env_id``.

        Fast (a file read, no training): the benchmark calls it on each training env at its
        option check, before anything runs, so that a missing or corrupt file is a bad option
        and not a failed run. The default does nothing.

        Raises
        ------
        CompensatorError
            Naming the file and what is wrong with it.
        """

    def env_note(self, env_id: str) -> str:
        """A sentence for the leaderboard of ``env_id`` about how this compensator runs there
        (a part it leaves off on that env, and why); ``""``: nothing to say. Computed without
        fitting (the leaderboard asks every compensator of its table)."""
        return ""

    # -- episode ------------------------------------------------------------------------------
    def reset(self, context: EpisodeContext, *, seed: int | None = None) -> None:
        """Start an episode on ``context.reference``."""
        if not isinstance(context, EpisodeContext):
            raise TypeError(f"context={context!r}: expected an EpisodeContext")
        if context.task.action != self.action_mode:
            raise ValueError(f"{self.id}: produces {self.action_mode!r} actions but the env "
                             f"expects {context.task.action!r}")
        if not self._fitted:
            raise NotFittedError(f"{self.id}: call fit() before reset()")
        self._context = context
        self._reset(context, seed)

    def act(self, observation: np.ndarray) -> np.ndarray:
        """Action in [-1, 1] for ``observation``; raises on NaN/inf output."""
        if self._context is None:
            raise RuntimeError(f"{self.id}: call reset() before act()")
        obs = np.asarray(observation, dtype=np.float64)
        if not np.all(np.isfinite(obs)):
            raise ValueError(f"{self.id}: observation contains NaN or inf")
        action = np.asarray(self._act(obs), dtype=np.float64).reshape(self._context.n_axes)
        if not np.all(np.isfinite(action)):
            raise CompensatorError(f"{self.id}: produced a non-finite action {action!r}")
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    def planned_actions(self, n_steps: int) -> np.ndarray | None:
        """The episode's next ``n_steps`` actions, shape (D, n_steps), when they do not depend
        on the observation (feedforward from the reference); ``None`` otherwise.

        Exactly what ``n_steps`` calls of :meth:`act` would return (float32 in [-1, 1]), and it
        advances the episode as they would. The runner then simulates the episode in one kernel
        call (:meth:`fricbench.gym.ServoAxisEnv.run_actions`). Subclasses write
        ``_planned``.
        """
        if self._context is None:
            raise RuntimeError(f"{self.id}: call reset() before planned_actions()")
        plan = self._planned(int(n_steps))
        if plan is None:
            return None
        d = self._context.n_axes
        a = np.asarray(plan, dtype=np.float64).reshape(d, int(n_steps))
        if not np.all(np.isfinite(a)):
            raise CompensatorError(f"{self.id}: produced a non-finite action")
        return np.clip(a, -1.0, 1.0).astype(np.float32)

    def _planned(self, n_steps: int) -> np.ndarray | None:
        """Open-loop compensators return their next ``n_steps`` actions (see
        :meth:`planned_actions`); the default, ``None``, means the action needs the
        observation."""
        return None

    def end_episode(self) -> None:  # noqa: B027 - optional hook
        """Called after the scored episode (optional hook)."""

    @classmethod
    def batch(cls, members: Sequence[Compensator]) -> CompensatorBatch:
        """One object acting for the episodes of ``members``, stepped together.

        ``members`` are instances of this class, each :meth:`reset` on its own episode (its
        plant's seed, its context) and not yet stepped. Row ``i`` of the batch's
        :meth:`CompensatorBatch.act` is member ``i``'s observation and action: exactly, bit for
        bit, what ``members[i].act`` would return, whatever the other rows (the benchmark steps
        the seeds of a cell together and its tests check this for every registered
        compensator). After this call the episode is the batch's: do not step the members.

        The default acts row by row through each member. Subclasses whose step vectorises
        over episodes (an observer bank, a policy network) return a
        :class:`CompensatorBatch` subclass that steps every row in one call.
        """
        return CompensatorBatch(members)

    # -- to implement -------------------------------------------------------------------------
    def _reset(self, context: EpisodeContext, seed: int | None) -> None:  # noqa: B027
        """Prepare for the episode (precompute feedforward, reset filters, ...)."""

    @abc.abstractmethod
    def _act(self, observation: np.ndarray) -> np.ndarray:
        """Action for a validated observation."""

    # -- helpers for subclasses ---------------------------------------------------------------
    @property
    def context(self) -> EpisodeContext:
        """The current episode's context."""
        if self._context is None:
            raise RuntimeError(f"{self.id}: no episode started")
        return self._context


class CompensatorBatch:
    """Episodes of one compensator class stepped together (:meth:`Compensator.batch`).

    Public :meth:`act` checks as :meth:`Compensator.act` does, per row; subclasses write
    ``_act_rows``. The default steps each member in turn.

    Parameters
    ----------
    members : sequence of Compensator
        Instances of one class, each reset on its episode; all on episodes with the same
        number of axes.
    """

    def __init__(self, members: Sequence[Compensator]) -> None:
        self.members = list(members)
        if not self.members:
            raise ValueError("members: expected at least one compensator")
        kinds = {type(m) for m in self.members}
        if len(kinds) > 1:
            raise TypeError(f"members: instances of {sorted(k.__name__ for k in kinds)}; "
                            "expected one class")
        dims = {m.context.n_axes for m in self.members}
        if len(dims) > 1:
            raise ValueError(f"members: episodes of {sorted(dims)} axes; expected one number")
        self.n_axes = dims.pop()

    def __len__(self) -> int:
        return len(self.members)

    def act(self, observations: np.ndarray) -> np.ndarray:
        """Actions in [-1, 1], shape (N, D) float32, for observations of shape (N, obs_dim);
        raises, naming the row, on NaN/inf in or out."""
        obs = np.asarray(observations, dtype=np.float64)
        if obs.ndim != 2 or obs.shape[0] != len(self.members):
            raise ValueError(f"observations has shape {obs.shape}: expected "
                             f"({len(self.members)}, obs_dim)")
        bad = ~np.isfinite(obs).all(axis=1)
        if bad.any():
            raise ValueError(f"{self.members[0].id}: observation of row {int(np.argmax(bad))} "
                             "contains NaN or inf")
        action = np.asarray(self._act_rows(obs), dtype=np.float64).reshape(len(self.members),
                                                                           self.n_axes)
        bad = ~np.isfinite(action).all(axis=1)
        if bad.any():
            i = int(np.argmax(bad))
            raise CompensatorError(f"{self.members[0].id}: produced a non-finite action "
                                   f"{action[i]!r} (row {i})")
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    def _act_rows(self, observations: np.ndarray) -> np.ndarray:
        """Actions of every row for validated observations (default: each member's act)."""
        return np.stack([m.act(o) for m, o in zip(self.members, observations, strict=True)])

    def end_episode(self) -> None:
        """Each member's :meth:`Compensator.end_episode`."""
        for m in self.members:
            m.end_episode()
