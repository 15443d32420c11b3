"""``tf-precomp``, ``tf-lstm-precomp``, ``greybox-precomp``: pre-compensation with a
tracking-error predictor.

Thin wrappers over the predictors of :mod:`fricbench.predictors` (ids ``tf``, ``tf+lstm`` and
``greybox``). :meth:`Precompensation.fit` records uncompensated runs of the env's nominal
axis on *training* references (the seeded ``random`` mixture) and fits the predictor on
them; at :meth:`~Precompensation.reset` the whole offset sequence for the episode's
reference is computed once by
:func:`fricbench.predictors.precomp.precompensation_offset` (the reference is shifted by the
predicted error, ``iterations`` times refined on the predictor, each step scaled by ``gain``
and applied ``advance`` samples early), and :meth:`act` replays it.
The env runs in offset mode with ``action_scale`` m per unit action (the bench sizes it from the
env's own tracking-error scale: :attr:`fricbench.gym.task.TaskConfig.offset_scale`).
"""

from __future__ import annotations

import inspect
from typing import Any, ClassVar

import numpy as np

from fricbench._validation import check_int, check_positive, check_range
from fricbench.axis import Axis, simulate
from fricbench.compensators.base import Compensator, CompensatorError, EpisodeContext
from fricbench.compensators.training_data import env_setup, training_references
from fricbench.predictors import make_predictor, predictor_registry
from fricbench.predictors.precomp import precompensation_offset
from fricbench.registry import did_you_mean

__all__ = ["Precompensation"]


class Precompensation(Compensator):
    """Reference offset from a fitted tracking-error predictor (any registered one).

    Registered variants: ``tf-precomp`` (``predictor="tf"``), ``tf-lstm-precomp``
    (``"tf+lstm"``, the paper's plain shift) and ``greybox-precomp`` (``"greybox"``, refined 10
    times with gain 0.5, each correction 3 samples early: the setting ``fricbench reproduce``
    picks for it on its training references). Any registered predictor is benchable as
    ``precomp:<predictor id>`` (:func:`fricbench.compensators.make_compensator`).

    Parameters
    ----------
    predictor : str
        Registered predictor id (``fricbench list`` shows them).
    n_runs : int
        Training references recorded in :meth:`fit`.
    run_duration : float
        Length of each training reference, s.
    iterations : int
        Refinements of the offset on the predictor (1: shift by the predicted error).
    gain : float
        Step of each refinement, in (0, 1].
    advance : int
        Samples by which each correction is applied earlier (phase lead).
    predictor_kwargs : dict or None
        Constructor keywords of the predictor. Predictors that take ``n_threads`` and
        ``verbose`` get 1 and 0 unless given here (the bench fans out over cores itself).

    Attributes
    ----------
    predictor_ : Predictor
        The fitted predictor.
    """

    id = "precomp"
    action_mode: ClassVar[str] = "offset"
    learns: ClassVar[bool] = True
    category: ClassVar[str] = "model"

    def __init__(self, *, predictor: str = "tf", n_runs: int = 4, run_duration: float = 20.0,
                 iterations: int = 1, gain: float = 1.0, advance: int = 0,
                 predictor_kwargs: dict[str, Any] | None = None) -> None:
        super().__init__()
        if not isinstance(predictor, str) or predictor not in predictor_registry:
            hint = did_you_mean(predictor, predictor_registry.ids())
            raise ValueError(f"predictor={predictor!r}: not a registered predictor id{hint}; "
                             f"expected one of {', '.join(predictor_registry.ids())}")
        check_int("n_runs", n_runs, 1, 1000)
        check_positive("run_duration", run_duration, "s")
        check_int("iterations", iterations, 1, 100)
        check_range("gain", gain, 1e-6, 1.0)
        check_int("advance", advance, 0, 1000)
        if predictor_kwargs is not None and not isinstance(predictor_kwargs, dict):
            raise TypeError(f"predictor_kwargs={predictor_kwargs!r}: expected a dict or None")
        self.predictor = predictor
        self.n_runs = n_runs
        self.run_duration = run_duration
        self.iterations = iterations
        self.gain = gain
        self.advance = advance
        self.predictor_kwargs = predictor_kwargs
        self.id = f"precomp:{predictor}"
        self._u = np.zeros((1, 1))
        self._k = 0

    def _predictor_defaults(self) -> dict[str, Any]:
        entry = predictor_registry.spec(self.predictor)
        accepted = inspect.signature(entry.load()).parameters
        return {k: v for k, v in (("n_threads", 1), ("verbose", 0)) if k in accepted}

    def fit(self, env_id: str, *, seed: int = 0, axis: Axis | None = None) -> Precompensation:
        """Fit the predictor on uncompensated training runs of ``env_id``'s nominal axis (or of
        ``axis``, the machine the runs are recorded on: a benchmark seed's plant)."""
        if axis is None:
            axis, _ = env_setup(env_id)
        refs = training_references(self.n_runs, seed=seed, duration=self.run_duration,
                                   ts=axis.controller.ts)
        runs = [simulate(axis, r, seed=seed + i) for i, r in enumerate(refs)]
        kwargs = {**self._predictor_defaults(), **(self.predictor_kwargs or {})}
        self.predictor_ = make_predictor(self.predictor, **kwargs).fit(runs)
        self._fitted = True
        return self

    def _reset(self, context: EpisodeContext, seed: int | None) -> None:
        ref = context.reference
        # predictors work one axis at a time: offset each coordinate of a D-axis reference
        rows = [ref] if ref.n_axes == 1 else [ref.axis(i) for i in range(ref.n_axes)]
        offset = np.array([np.asarray(precompensation_offset(
            self.predictor_, r, iterations=self.iterations, gain=self.gain,
            advance=self.advance), dtype=float) for r in rows])
        if offset.shape != (ref.n_axes, ref.n_samples):
            raise CompensatorError(f"{self.id}: predictor returned an offset of shape "
                                   f"{offset.shape}; expected ({ref.n_axes}, {ref.n_samples})")
        if not np.all(np.isfinite(offset)):
            raise CompensatorError(f"{self.id}: predictor returned a non-finite offset")
        self._u = offset / context.task.action_scale
        self._k = 0

    def _act(self, observation: np.ndarray) -> np.ndarray:
        k = min(self._k, self._u.shape[1] - 1)
        self._k += 1
        return self._u[:, k]

    def _planned(self, n_steps: int) -> np.ndarray:
        idx = np.minimum(self._k + np.arange(n_steps), self._u.shape[1] - 1)
        self._k += n_steps
        return self._u[:, idx]
