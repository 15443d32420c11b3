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
* a saved predictor is one zip file holding ``config.json`` (format version, registered
  predictor id, constructor arguments) and ``weights.pt`` (a ``state_dict`` of floating
  tensors, read back with ``torch.load(..., weights_only=True)``). Loading imports nothing the
  file names, and checks sizes before inflating anything. A file of another format version,
  naming an unregistered class, with tensors of the wrong dtype or shape, too large, or not a
  predictor file at all raises :class:`PredictorFileError` naming the file and the field.
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
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch

from fricbench._atomic import atomic_write
from fricbench._safe_load import (
    MAX_MODEL_BYTES,
    UnsafeFileError,
    load_tensors,
    parse_json,
    read_file,
    read_members,
)
from fricbench.exceptions import NotFittedError
from fricbench.registry import RegistryEntry
from fricbench.run import Run, validate_run_arrays
from fricbench.sysid.friction_error import find_events
from fricbench.trajectories.base import Reference

__all__ = ["Run", "as_runs", "Predictor", "NotFittedError", "PredictorFileError",
           "FORMAT_VERSION"]

FORMAT_VERSION = 1
_FORMAT_NAME = "fricbench.predictor"

P = TypeVar("P", bound="Predictor")


class PredictorFileError(ValueError):
    """A saved predictor that cannot be loaded; the message names the file and the problem."""


def _run_arrays(obj: Any, i: int) -> Run:
    for name in ("t", "x_ref", "x"):
        if not hasattr(obj, name):
            raise TypeError(f"runs[{i}]={type(obj).__name__}: expected a Run or a "
                            f"SimulationResult (an object with t, x_ref and x); missing {name!r}")
    arrs, _ = validate_run_arrays(obj.t, obj.x_ref, obj.x, min_samples=3,
                                  labels={key: f"runs[{i}].{key}" for key in ("t", "x_ref", "x")})
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
        """Save constructor arguments and learned weights to one file (written atomically).

        The file names the predictor by its registered id (see :func:`_registered_id`), never
        by a module path.

        Raises
        ------
        NotFittedError
            Before :meth:`fit`.
        ValueError
            The class is not registered in ``predictor_registry`` (its file could not be
            loaded back).
        """
        self._check_fitted()
        params = _to_json(self.get_params())
        config = {
            "format": _FORMAT_NAME,
            "version": FORMAT_VERSION,
            "class": _registered_id(type(self), params),
            "params": params,
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

        The file is data only: its ``"class"`` field must be a registered predictor id (or,
        in files written before ids were stored, exactly the ``"module:Class"`` entry point a
        registered id names); no module named by the file is ever imported. The archive must
        hold exactly ``config.json`` and ``weights.pt``, declaring at most
        :data:`~fricbench._safe_load.MAX_MODEL_BYTES` uncompressed; every tensor must be a
        dense floating tensor of the shape the class expects.

        Raises
        ------
        PredictorFileError
            Missing, oversized or corrupt file, another format or version, an unregistered
            or foreign class, constructor arguments the class rejects, or weights of the wrong
            names, dtypes or shapes. The message names the file and the field.
        """
        path = Path(path)
        try:
            members = read_members(read_file(path, MAX_MODEL_BYTES), str(path),
                                   ("config.json", "weights.pt"))
            config = parse_json(members["config.json"], f"{path}: config.json")
        except FileNotFoundError:
            raise PredictorFileError(f"{path}: no such file") from None
        except UnsafeFileError as exc:
            raise PredictorFileError(str(exc)) from None
        fmt = config.get("format") if isinstance(config, dict) else None
        if not isinstance(config, dict) or fmt != _FORMAT_NAME:
            raise PredictorFileError(f"{path}: not a fricbench predictor file (config.json "
                                     f"format={_short(fmt)}; expected {_FORMAT_NAME!r})")
        version = config.get("version")
        if version != FORMAT_VERSION or isinstance(version, bool):
            raise PredictorFileError(f"{path}: config.json: format version {_short(version)}, "
                                     f"this fricbench reads version {FORMAT_VERSION}")
        klass = _resolve_class(path, config.get("class"))
        if cls is not Predictor and not issubclass(klass, cls):
            raise PredictorFileError(f"{path}: holds a {klass.__name__}, not a {cls.__name__}")
        try:
            obj = klass(**_from_json(klass, config.get("params", {})))
        except (TypeError, ValueError, KeyError) as exc:
            raise PredictorFileError(f"{path}: config.json params: bad constructor arguments "
                                     f"for {klass.__name__} ({exc})") from None
        try:
            state = load_tensors(members["weights.pt"], f"{path}: weights.pt")
        except UnsafeFileError as exc:
            raise PredictorFileError(str(exc)) from None
        ts_t = state.pop("ts_", None)
        if ts_t is None or ts_t.shape != ():
            shape = None if ts_t is None else tuple(ts_t.shape)
            raise PredictorFileError(f"{path}: weights.pt: tensor 'ts_' (sample time) has "
                                     f"shape {shape}; expected a scalar, shape ()")
        ts = float(ts_t)
        if not (math.isfinite(ts) and ts > 0):
            raise PredictorFileError(f"{path}: weights.pt: tensor 'ts_' (sample time) is "
                                     f"{ts!r}; expected a positive number of seconds")
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
                        f"{path}: weights.pt: tensor {name!r} has shape "
                        f"{tuple(state[name].shape)} but "
                        f"{klass.__name__} built from the file's config expects {tuple(shape)}")
        try:
            obj._set_state(state)
        except (KeyError, ValueError, RuntimeError) as exc:
            raise PredictorFileError(f"{path}: weights do not fit {klass.__name__} ({exc})") \
                from None
        obj.ts_ = ts
        return obj  # type: ignore[return-value]  # klass is cls or a subclass (checked above)


def _short(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters (values read from a file can be huge)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _entry_matches(entry: RegistryEntry, klass: type) -> bool:
    """Whether ``entry`` names ``klass``, compared as strings: nothing is imported."""
    if isinstance(entry.entry_point, str):
        return entry.entry_point == f"{klass.__module__}:{klass.__qualname__}"
    return entry.entry_point is klass


def _registered_id(klass: type[Predictor], params: dict[str, Any]) -> str:
    """The predictor id that a saved ``klass`` instance is filed under.

    Of the registered ids whose entry point is ``klass``, the one whose registered defaults
    all equal ``params`` and are the most numerous (``tf+lstm-phys`` for a ``TFLSTMPredictor``
    with ``features="physical"``); the saved parameters are complete, so any of them loads
    the same predictor.
    """
    from fricbench.predictors.registered import predictor_registry

    best: tuple[int, str] | None = None
    for pid in predictor_registry.ids():
        entry = predictor_registry.spec(pid)
        if not _entry_matches(entry, klass):
            continue
        n = len(entry.kwargs)
        if any(params.get(k) != _to_json({k: v})[k] for k, v in entry.kwargs.items()):
            n = -1
        if best is None or n > best[0]:
            best = (n, pid)
    if best is None:
        raise ValueError(f"{klass.__module__}:{klass.__qualname__} is not registered in "
                         "fricbench.predictors.predictor_registry: register it under an id "
                         "to save it (a saved predictor names its class by id)")
    return best[1]


def _resolve_class(path: Path, value: Any) -> type[Predictor]:
    """The class of a file's ``"class"`` field, through the registry only.

    ``value`` must be a registered id, or exactly the string entry point of a registered id
    (files written before ids were stored); the class is then loaded from the registry's own
    entry point. A module named only by the file is never imported.
    """
    from fricbench.predictors.registered import predictor_registry

    if not isinstance(value, str):
        raise PredictorFileError(f"{path}: config.json class={_short(value)}: expected a "
                                 "registered predictor id")
    entry: RegistryEntry | None
    if value in predictor_registry:
        entry = predictor_registry.spec(value)
    else:  # a file written before ids were stored: the exact entry-point string of an id
        entry = next((predictor_registry.spec(pid) for pid in predictor_registry.ids()
                      if predictor_registry.spec(pid).entry_point == value), None)
        if entry is None:
            raise PredictorFileError(
                f"{path}: config.json class={_short(value)} is not a registered predictor id "
                f"(registered: {', '.join(predictor_registry.ids())}); a predictor file names "
                "its class by id and is never used to import code")
    try:
        klass = entry.load()
    except (ImportError, ValueError) as exc:  # a registered plug-in that is broken
        raise PredictorFileError(f"{path}: predictor {entry.id!r} cannot be loaded "
                                 f"({exc})") from None
    if not (isinstance(klass, type) and issubclass(klass, Predictor)):
        raise PredictorFileError(f"{path}: predictor {entry.id!r} is registered as "
                                 f"{klass!r}, not a Predictor class")
    return klass


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
