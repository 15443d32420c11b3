"""The ``Predictor`` API: tracking-error predictors in the scikit-learn shape.

A predictor learns, from logged runs of an axis, to predict the position the axis will reach
on a new reference::

    pred = make_predictor("tf+lstm").fit(runs)     # runs: SimulationResult or Run objects
    x_pred = pred.predict(reference)               # m, shape (K,)
    e_pred = pred.predict_error(reference)         # x_ref - x_pred, m
    pred.save("model.fbp"); pred2 = Predictor.load("model.fbp")

Conventions (scikit-learn / stable-baselines3):

* constructor keyword arguments are stored as given (``get_params``) and validated;
* ``fit`` returns ``self``; learned attributes end in ``_``; ``predict`` before ``fit`` raises
  :class:`NotFittedError`;
* the public ``fit``/``predict`` validate the data once, subclasses write only the kernels
  ``_fit(runs, ts)`` and ``_predict_position(x_ref)``;
* a saved predictor is one zip file holding ``config.json`` (format version, class, constructor
  arguments) and ``weights.pt`` (a ``state_dict`` of tensors, read back with
  ``torch.load(..., weights_only=True)``). A file of another format version, with tensors of the
  wrong shape, or not a predictor file at all raises :class:`PredictorFileError` naming it.
"""

from __future__ import annotations

import inspect
import io
import json
import math
import os
import zipfile
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch

from fricbench._atomic import atomic_write
from fricbench.registry import load_entry_point
from fricbench.sysid.friction_error import find_events
from fricbench.trajectories.base import Reference

__all__ = ["Run", "as_runs", "Predictor", "NotFittedError", "PredictorFileError",
           "FORMAT_VERSION"]

FORMAT_VERSION = 1
_FORMAT_NAME = "fricbench.predictor"

P = TypeVar("P", bound="Predictor")


class NotFittedError(RuntimeError):
    """``predict`` (or ``save``) called before ``fit``."""


class PredictorFileError(ValueError):
    """A saved predictor that cannot be loaded; the message names the file and the problem."""


@dataclass(frozen=True)
class Run:
    """One logged run: what a predictor is fitted on.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Time, s, uniformly sampled.
    x_ref : ndarray, shape (K,)
        Reference position, m.
    x : ndarray, shape (K,)
        Measured position, m.
    """

    t: np.ndarray
    x_ref: np.ndarray
    x: np.ndarray

    @property
    def ts(self) -> float:
        """Sample time, s."""
        return float(self.t[1] - self.t[0])


def _run_arrays(obj: Any, i: int) -> Run:
    for name in ("t", "x_ref", "x"):
        if not hasattr(obj, name):
            raise TypeError(f"runs[{i}]={type(obj).__name__}: expected a Run or a "
                            f"SimulationResult (an object with t, x_ref and x); missing {name!r}")
    arrs = {}
    for name in ("t", "x_ref", "x"):
        a = np.asarray(getattr(obj, name), dtype=float)
        if a.ndim != 1:
            raise ValueError(f"runs[{i}].{name} has shape {a.shape}: expected a 1-D array "
                             "(a single-axis run)")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise ValueError(f"runs[{i}].{name} contains NaN or inf (first at sample {bad[0]})")
        arrs[name] = a
    k = arrs["t"].shape[0]
    for name in ("x_ref", "x"):
        if arrs[name].shape[0] != k:
            raise ValueError(f"runs[{i}]: t has {k} samples but {name} has "
                             f"{arrs[name].shape[0]}: every array must have the same length")
    if k < 3:
        raise ValueError(f"runs[{i}] has {k} samples: need at least 3")
    dt = np.diff(arrs["t"])
    if dt[0] <= 0 or np.max(np.abs(dt - dt[0])) > 1e-6 * dt[0]:
        raise ValueError(f"runs[{i}].t is not uniformly increasing: predictors need one sample "
                         "time per run")
    return Run(arrs["t"], arrs["x_ref"], arrs["x"])


def as_runs(runs: Any) -> tuple[list[Run], float]:
    """Validate ``runs`` and return them as :class:`Run` objects with their common sample time.

    Raises
    ------
    TypeError
        Not a non-empty sequence of run-like objects.
    ValueError
        NaN/inf, arrays of different lengths, non-uniform time, different sample times, or a
        run without motion.
    """
    if hasattr(runs, "x_ref") or not isinstance(runs, Sequence) or isinstance(runs, str):
        raise TypeError(f"runs={type(runs).__name__}: expected a list of runs (wrap a single "
                        "run in a list)")
    if len(runs) == 0:
        raise ValueError("runs is empty: expected at least one run")
    out = [_run_arrays(r, i) for i, r in enumerate(runs)]
    ts = out[0].ts
    for i, r in enumerate(out):
        if abs(r.ts - ts) > 1e-6 * ts:
            raise ValueError(f"runs[{i}] is sampled at ts={r.ts:g} s but runs[0] at {ts:g} s: "
                             "every run must have the same sample time")
        if np.ptp(r.x_ref) <= 0.0:
            raise ValueError(f"runs[{i}] has no motion (x_ref is constant): nothing to learn "
                             "from")
    return out, ts


def check_direction_changes(runs: Sequence[Run], ts: float) -> None:
    """Raise unless the runs contain at least one reversal of the direction of motion.

    A direct reversal counts, and so does a stop followed by a start the other way.
    """
    for r in runs:
        last_dir = 0
        for ev in find_events(r.x_ref, ts):
            if ev.kind == "reversal":
                return
            if ev.kind in ("start", "stop"):
                if ev.kind == "start" and last_dir and ev.direction != last_dir:
                    return
                last_dir = ev.direction
    raise ValueError("the runs have no reversal of the direction of motion: friction "
                     "predictors learn from reversals (and starts), fit on a run that goes "
                     "both ways")


class Predictor(ABC):
    """Base class of tracking-error predictors.

    Subclasses define ``__init__`` with explicit keyword arguments stored under the same names,
    and implement :meth:`_fit`, :meth:`_predict_position`, :meth:`_state` and
    :meth:`_set_state`.

    Attributes
    ----------
    needs_reversals : bool
        Whether ``fit`` requires a reversal of direction in the runs (class attribute).
    ts_ : float
        Sample time of the training data, s (after ``fit``).
    """

    needs_reversals: ClassVar[bool] = True

    # -- parameters ---------------------------------------------------------------------------
    def get_params(self) -> dict[str, Any]:
        """Constructor arguments, as given (JSON-ready)."""
        sig = inspect.signature(type(self).__init__)
        return {name: getattr(self, name) for name in sig.parameters if name != "self"}

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    @property
    def is_fitted(self) -> bool:
        """Whether :meth:`fit` has run."""
        return hasattr(self, "ts_")

    def _check_fitted(self) -> None:
        if not self.is_fitted:
            raise NotFittedError(f"this {type(self).__name__} is not fitted yet: call "
                                 "fit(runs) first")

    # -- learning -----------------------------------------------------------------------------
    def fit(self: P, runs: Sequence[Any]) -> P:
        """Learn from logged runs.

        Parameters
        ----------
        runs : list of Run or SimulationResult
            Single-axis runs with the same sample time; each needs motion, and friction
            predictors need a reversal of direction somewhere.

        Returns
        -------
        self
        """
        checked, ts = as_runs(runs)
        if self.needs_reversals:
            check_direction_changes(checked, ts)
        self._fit(checked, ts)
        self.ts_ = ts
        return self

    def _check_reference(self, reference: Reference) -> np.ndarray:
        self._check_fitted()
        if not isinstance(reference, Reference):
            raise TypeError(f"reference={type(reference).__name__}: expected a "
                            "fricbench.trajectories.Reference")
        if reference.n_axes != 1:
            raise ValueError(f"reference has {reference.n_axes} axes: predict one axis at a "
                             "time (reference.axis(i))")
        if reference.n_samples < 3:
            raise ValueError(f"reference has {reference.n_samples} samples: need at least 3")
        if abs(reference.ts - self.ts_) > 1e-6 * self.ts_:
            raise ValueError(f"reference is sampled at ts={reference.ts:g} s but the predictor "
                             f"was fitted at ts={self.ts_:g} s: resample the reference to "
                             f"{self.ts_:g} s")
        return np.asarray(reference.x, dtype=float)

    def predict(self, reference: Reference) -> np.ndarray:
        """Predicted measured position on ``reference``, m, shape (K,)."""
        x_ref = self._check_reference(reference)
        out = np.asarray(self._predict_position(x_ref), dtype=float)
        if out.shape != x_ref.shape:  # pragma: no cover - kernel contract
            raise RuntimeError(f"{type(self).__name__}._predict_position returned shape "
                               f"{out.shape} for {x_ref.shape}")
        return out

    def predict_error(self, reference: Reference) -> np.ndarray:
        """Predicted tracking error ``x_ref - x_pred``, m, shape (K,)."""
        return np.asarray(reference.x, dtype=float) - self.predict(reference)

    @abstractmethod
    def _fit(self, runs: list[Run], ts: float) -> None:
        """Learn from validated runs (same ``ts``); set attributes ending in ``_``."""

    @abstractmethod
    def _predict_position(self, x_ref: np.ndarray) -> np.ndarray:
        """Predicted position for a validated reference (sample time ``ts_``)."""

    @abstractmethod
    def _state(self) -> dict[str, torch.Tensor]:
        """Learned state as named tensors (``ts_`` excluded)."""

    @abstractmethod
    def _set_state(self, state: dict[str, torch.Tensor]) -> None:
        """Restore learned state from :meth:`_state`'s output (shapes already checked)."""

    def _expected_shapes(self, state: dict[str, torch.Tensor]) -> dict[str, tuple[int, ...]] | None:
        """Shapes the unfitted instance expects for ``state`` (``None``: accept any)."""
        return None

    # -- persistence --------------------------------------------------------------------------
    def save(self, path: str | os.PathLike[str]) -> None:
        """Save constructor arguments and learned weights to one file (written atomically)."""
        self._check_fitted()
        config = {
            "format": _FORMAT_NAME,
            "version": FORMAT_VERSION,
            "class": f"{type(self).__module__}:{type(self).__qualname__}",
            "params": _to_json(self.get_params()),
        }
        state = dict(self._state())
        state["ts_"] = torch.tensor(self.ts_, dtype=torch.float64)
        buf = io.BytesIO()
        torch.save(state, buf)
        out = io.BytesIO()
        with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("config.json", json.dumps(config, indent=2))
            zf.writestr("weights.pt", buf.getvalue())
        atomic_write(path, out.getvalue())

    @classmethod
    def load(cls: type[P], path: str | os.PathLike[str]) -> P:
        """Load a predictor saved by :meth:`save`.

        Called on :class:`Predictor`, returns whatever class the file holds; called on a
        subclass, the file must hold that subclass.

        Raises
        ------
        PredictorFileError
            Missing or corrupt file, another format or version, another class, constructor
            arguments the class rejects, or weights of the wrong names or shapes.
        """
        path = Path(path)
        try:
            with zipfile.ZipFile(path) as zf:
                config = json.loads(zf.read("config.json"))
                raw = zf.read("weights.pt")
        except FileNotFoundError:
            raise PredictorFileError(f"{path}: no such file") from None
        except (zipfile.BadZipFile, KeyError, json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise PredictorFileError(f"{path}: not a fricbench predictor file ({exc})") from None
        fmt = config.get("format") if isinstance(config, dict) else None
        if not isinstance(config, dict) or fmt != _FORMAT_NAME:
            raise PredictorFileError(f"{path}: not a fricbench predictor file (format {fmt!r})")
        if config.get("version") != FORMAT_VERSION:
            raise PredictorFileError(f"{path}: format version {config.get('version')!r}, this "
                                     f"fricbench reads version {FORMAT_VERSION}")
        try:
            klass = load_entry_point(str(config.get("class")))
        except (ImportError, ValueError) as exc:
            raise PredictorFileError(f"{path}: unknown predictor class ({exc})") from None
        if not (isinstance(klass, type) and issubclass(klass, Predictor)):
            raise PredictorFileError(f"{path}: {config.get('class')!r} is not a Predictor")
        if cls is not Predictor and not issubclass(klass, cls):
            raise PredictorFileError(f"{path}: holds a {klass.__name__}, not a {cls.__name__}")
        try:
            obj = klass(**_from_json(klass, config.get("params", {})))
        except (TypeError, ValueError) as exc:
            raise PredictorFileError(f"{path}: bad constructor arguments ({exc})") from None
        try:
            state = torch.load(io.BytesIO(raw), weights_only=True)
        except Exception as exc:  # torch raises several unrelated types on corrupt input
            raise PredictorFileError(f"{path}: weights.pt is unreadable ({exc})") from None
        if not isinstance(state, dict) or "ts_" not in state or not all(
                isinstance(v, torch.Tensor) for v in state.values()):
            raise PredictorFileError(f"{path}: weights.pt is not a state_dict of tensors")
        ts = float(state.pop("ts_"))
        if not (math.isfinite(ts) and ts > 0):
            raise PredictorFileError(f"{path}: stored sample time {ts!r} is not positive")
        expected = obj._expected_shapes(state)
        if expected is not None:
            missing = sorted(set(expected) - set(state))
            extra = sorted(set(state) - set(expected))
            if missing or extra:
                raise PredictorFileError(f"{path}: weights do not match {klass.__name__} "
                                         f"(missing {missing}, unexpected {extra})")
            for name, shape in expected.items():
                if tuple(state[name].shape) != tuple(shape):
                    raise PredictorFileError(
                        f"{path}: tensor {name!r} has shape {tuple(state[name].shape)} but "
                        f"{klass.__name__} built from the file's config expects {tuple(shape)}")
        try:
            obj._set_state(state)
        except (KeyError, ValueError, RuntimeError) as exc:
            raise PredictorFileError(f"{path}: weights do not fit {klass.__name__} ({exc})") \
                from None
        obj.ts_ = ts
        return obj  # type: ignore[return-value]  # klass is cls or a subclass (checked above)


def _to_json(params: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for k, v in params.items():
        if hasattr(v, "to_dict"):
            v = {"__axis__": v.to_dict()}
        elif isinstance(v, tuple):
            v = list(v)
        out[k] = v
    json.dumps(out)  # raises TypeError early if a parameter is not JSON-ready
    return out


def _from_json(klass: type, params: Any) -> dict[str, Any]:
    if not isinstance(params, dict):
        raise TypeError(f"params must be a dict, got {type(params).__name__}")
    out = {}
    for k, v in params.items():
        if isinstance(v, dict) and "__axis__" in v:
            from fricbench.axis import Axis

            v = Axis.from_dict(v["__axis__"])
        out[k] = v
    return out
