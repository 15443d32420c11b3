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
The env runs in offset mode with ``action_scale`` m per unit action.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from fricbench._validation import check_int, check_positive, check_range
from fricbench.axis import simulate
from fricbench.compensators.base import Compensator, CompensatorError, EpisodeContext
from fricbench.compensators.training_data import env_setup, training_references

__all__ = ["Precompensation", "TFPrecompensation", "TFLSTMPrecompensation",
           "GreyBoxPrecompensation"]


def _predictor_api() -> tuple[Any, Any]:
    """``make_predictor`` and ``precompensation_offset``; ImportError when not installed."""
    try:
        from fricbench.predictors import make_predictor
        from fricbench.predictors.precomp import precompensation_offset
    except ImportError as exc:
        raise ImportError(f"pre-compensation needs fricbench.predictors (make_predictor, "
                          f"predictors.precomp.precompensation_offset): {exc}") from exc
    return make_predictor, precompensation_offset


class Precompensation(Compensator):
    """Reference offset from a fitted tracking-error predictor.

    Parameters
    ----------
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
        Constructor keywords of the predictor, over :attr:`predictor_defaults`.

    Attributes
    ----------
    predictor_ : object
        The fitted predictor.
    """

    predictor_id: ClassVar[str] = ""
    #: predictor keywords used unless ``predictor_kwargs`` overrides them
    predictor_defaults: ClassVar[dict[str, Any]] = {}
    action_mode: ClassVar[str] = "offset"
    learns: ClassVar[bool] = True
    #: preferred env ``action_scale`` in offset mode, m per unit action
    action_scale: ClassVar[float] = 1.0e-4

    def __init__(self, *, n_runs: int = 4, run_duration: float = 20.0, iterations: int = 1,
                 gain: float = 1.0, advance: int = 0,
                 predictor_kwargs: dict[str, Any] | None = None) -> None:
        super().__init__()
        check_int("n_runs", n_runs, 1, 1000)
        check_positive("run_duration", run_duration, "s")
        check_int("iterations", iterations, 1, 100)
        check_range("gain", gain, 1e-6, 1.0)
        check_int("advance", advance, 0, 1000)
        if predictor_kwargs is not None and not isinstance(predictor_kwargs, dict):
            raise TypeError(f"predictor_kwargs={predictor_kwargs!r}: expected a dict or None")
        self.n_runs = n_runs
        self.run_duration = run_duration
        self.iterations = iterations
        self.gain = gain
        self.advance = advance
        self.predictor_kwargs = predictor_kwargs
        self._u = np.zeros((1, 1))
        self._k = 0

    def fit(self, env_id: str, *, seed: int = 0) -> Precompensation:
        """Fit the predictor on uncompensated training runs of ``env_id``'s nominal axis."""
        make_predictor, _ = _predictor_api()
        axis, _ = env_setup(env_id)
        refs = training_references(self.n_runs, seed=seed, duration=self.run_duration,
                                   ts=axis.controller.ts)
        runs = [simulate(axis, r, seed=seed + i) for i, r in enumerate(refs)]
        kwargs = {**self.predictor_defaults, **(self.predictor_kwargs or {})}
        self.predictor_ = make_predictor(self.predictor_id, **kwargs).fit(runs)
        self._fitted = True
        return self

    def _reset(self, context: EpisodeContext, seed: int | None) -> None:
        _, precompensation_offset = _predictor_api()
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


class TFPrecompensation(Precompensation):
    """Pre-compensation with the transfer-function predictor (``tf``)."""

    id: ClassVar[str] = "tf-precomp"
    predictor_id: ClassVar[str] = "tf"


class TFLSTMPrecompensation(Precompensation):
    """Pre-compensation with the TF + LSTM residual predictor (``tf+lstm``)."""

    id: ClassVar[str] = "tf-lstm-precomp"
    predictor_id: ClassVar[str] = "tf+lstm"
    #: one torch thread (the bench fans out over cores itself), silent training
    predictor_defaults: ClassVar[dict[str, Any]] = {"n_threads": 1, "verbose": 0}


class GreyBoxPrecompensation(Precompensation):
    """Pre-compensation with the identified closed loop (``greybox``).

    The offset is refined on the model 10 times with gain 0.5, each correction 3 samples
    early: the setting ``fricbench reproduce`` picks for this predictor on its training
    references (a one-shot shift moves the breakaway and leaves most of the spike; the model
    is cheap to run, so iterating on it costs little).
    """

    id: ClassVar[str] = "greybox-precomp"
    predictor_id: ClassVar[str] = "greybox"

    def __init__(self, *, n_runs: int = 4, run_duration: float = 20.0, iterations: int = 10,
                 gain: float = 0.5, advance: int = 3,
                 predictor_kwargs: dict[str, Any] | None = None) -> None:
        super().__init__(n_runs=n_runs, run_duration=run_duration, iterations=iterations,
                         gain=gain, advance=advance, predictor_kwargs=predictor_kwargs)
