"""What the envs share: the task settings, observation layout, reward and reference handling.

The scalar env (:mod:`fricbench.gym.env`) and the native vector env (:mod:`fricbench.gym.vector`)
both hold an :class:`~fricbench.axis.AxisBatch` (one row per simulated axis) and use the functions
here to turn references and kernel readings into observations and rewards, so the two cannot
drift apart.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from functools import lru_cache
from typing import Any

import numba
import numpy as np

from fricbench._memory import check_memory
from fricbench._validation import (
    check_choice,
    check_int,
    check_nonneg,
    check_positive,
)
from fricbench.axis import Axis
from fricbench.axis.kernel import P_KT, P_TS, S_IAPP, S_XFB, S_XFB_PREV, S_XMEAS
from fricbench.friction import make_friction
from fricbench.trajectories import Reference, make_trajectory

__all__ = [
    "OFFSET_RANGE",
    "REFERENCE_BYTES_PER_SAMPLE",
    "ObservationConfig",
    "Randomization",
    "RewardConfig",
    "TaskConfig",
    "TrajectoryChoice",
    "action_array",
    "apply_action",
    "check_action",
    "fill_observation",
    "observe_row",
    "n_features",
    "reference_for",
]


@dataclass(frozen=True)
class ObservationConfig:
    """Observation scaling and preview (every feature divided by its scale, so O(1)).

    Parameters
    ----------
    error_scale : float
        Tracking error scale, m (1e-5: 10 um -> 1).
    position_scale : float
        Reference position scale, m.
    velocity_scale : float
        Reference and measured velocity scale, m/s.
    acceleration_scale : float
        Reference acceleration scale, m/s^2.
    force_scale : float
        Motor force scale, N.
    preview : int
        Number of future reference samples (velocity and acceleration) in the observation.
    preview_stride : int
        Samples between preview points (5 x 10 samples = 50 ms look-ahead at 1 ms).
    """

    error_scale: float = 1.0e-5
    position_scale: float = 0.1
    velocity_scale: float = 0.05
    acceleration_scale: float = 1.0
    force_scale: float = 1000.0
    preview: int = 5
    preview_stride: int = 10

    def __post_init__(self) -> None:
        for name in ("error_scale", "position_scale", "velocity_scale", "acceleration_scale",
                     "force_scale"):
            check_positive(name, getattr(self, name))
        check_int("preview", self.preview, 0, 100)
        check_int("preview_stride", self.preview_stride, 1, 1000)


@dataclass(frozen=True)
class RewardConfig:
    """``r = -(e / error_scale)^2 - action_weight * |a|^2`` per step (``a`` in [-1, 1]).

    Parameters
    ----------
    error_scale : float
        Error that costs 1 per step, m.
    action_weight : float
        Weight of the squared scaled action.
    """

    error_scale: float = 1.0e-5
    action_weight: float = 0.01

    def __post_init__(self) -> None:
        check_positive("reward.error_scale", self.error_scale, "m")
        check_nonneg("reward.action_weight", self.action_weight)


@dataclass(frozen=True)
class Randomization:
    """Per-episode friction randomisation: ``{parameter: [low, high]}`` drawn uniformly.

    Keys are fields of the env's friction model (``fc``, ``vs``, ...) plus ``fs_ratio``
    (``fs = fs_ratio * fc``) and ``scale`` (multiplies ``fc``, ``fs`` and ``fv``).
    """

    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for key, rng in self.ranges.items():
            if len(rng) != 2 or not (float(rng[0]) <= float(rng[1])):
                raise ValueError(f"randomize.{key}={rng!r}: expected [low, high] with low <= high")

    def sample(self, axis: Axis, rng: np.random.Generator) -> Axis:
        """A copy of ``axis`` with freshly drawn friction parameters."""
        if not self.ranges:
            return axis
        params = axis.friction.to_dict()
        fid = params.pop("id")
        draws = {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in sorted(self.ranges.items())}
        scale = draws.pop("scale", 1.0)
        ratio = draws.pop("fs_ratio", None)
        for key, val in draws.items():
            if key not in params:
                raise ValueError(f"randomize.{key}: friction model {fid!r} has no such parameter "
                                 f"(has {sorted(params)})")
            params[key] = val
        if ratio is not None and "fs" in params:
            params["fs"] = ratio * params["fc"]
        for key in ("fc", "fs", "fv"):
            if key in params:
                params[key] *= scale
        if "fs" in params and params["fs"] < params["fc"]:
            params["fs"] = params["fc"]
        return replace(axis, friction=make_friction(fid, **params))


@dataclass(frozen=True)
class TrajectoryChoice:
    """A registered trajectory id and its parameters; ``seeded`` ones get a fresh seed each
    episode (the ``random`` training mixture)."""

    id: str
    params: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def parse(cls, item: str | Mapping[str, Any] | TrajectoryChoice) -> TrajectoryChoice:
        """Accept ``"m_serial"`` or ``{"id": "random", "duration": 10.0}``."""
        if isinstance(item, TrajectoryChoice):
            return item
        if isinstance(item, str):
            return cls(item)
        if isinstance(item, Mapping) and "id" in item:
            params = dict(item)
            return cls(str(params.pop("id")), params)
        raise TypeError(f"trajectory={item!r}: expected an id string or a table with 'id'")

    @property
    def seeded(self) -> bool:
        return self.id == "random" and "seed" not in self.params


OFFSET_RANGE = 10.0
"""Reach of a unit reference-offset action in units of the env's tracking-error scale
(``observation.error_scale``): a pre-compensator's offset is of the order of the error it
removes, so the range is sized from the env's own error, an order of magnitude above it
(:meth:`TaskConfig.offset_scale`; 10 um -> 0.1 mm on the paper axis, 0.578 mm -> 5.78 mm on the
EMPS twin, whose error is the lag of a loop without feedforward)."""


@dataclass(frozen=True)
class TaskConfig:
    """Everything about an env besides the axis.

    Parameters
    ----------
    trajectories : sequence of TrajectoryChoice
        The set ``reset`` draws from (uniformly, with the env's seeded generator).
    action : {"force", "offset"}
        ``force``: compensation force at the velocity-loop output, ``action_scale`` N per unit;
        ``offset``: reference offset (pre-compensation), ``action_scale`` m per unit.
    action_scale : float
        Physical size of a unit action (N or m).
    observation : ObservationConfig
    reward : RewardConfig
    randomize : Randomization
    """

    trajectories: tuple[TrajectoryChoice, ...] = (TrajectoryChoice("m_serial"),)
    action: str = "force"
    action_scale: float = 600.0
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    reward: RewardConfig = field(default_factory=RewardConfig)
    randomize: Randomization = field(default_factory=Randomization)

    def __post_init__(self) -> None:
        if not self.trajectories:
            raise ValueError("trajectories=(): expected at least one trajectory")
        check_choice("action", self.action, ("force", "offset"))
        check_positive("action_scale", self.action_scale)

    @property
    def offset_scale(self) -> float:
        """Size of a unit reference-offset action on this env, m: the spec's ``action_scale``
        when the env acts by offset, else :data:`OFFSET_RANGE` times ``observation.error_scale``
        (the action range a compensator acting by offset gets on a force env)."""
        if self.action == "offset":
            return self.action_scale
        return OFFSET_RANGE * self.observation.error_scale

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any]) -> TaskConfig:
        """Build from the ``[task]`` table of an env TOML (keys as in the constructor)."""
        allowed = {f.name for f in fields(cls)}
        unknown = set(spec) - allowed
        if unknown:
            raise ValueError(f"task: unknown keys {sorted(unknown)}; expected {sorted(allowed)}")
        kw: dict[str, Any] = dict(spec)
        if "trajectories" in kw:
            kw["trajectories"] = tuple(TrajectoryChoice.parse(t) for t in kw["trajectories"])
        if "observation" in kw and not isinstance(kw["observation"], ObservationConfig):
            kw["observation"] = ObservationConfig(**kw["observation"])
        if "reward" in kw and not isinstance(kw["reward"], RewardConfig):
            kw["reward"] = RewardConfig(**kw["reward"])
        if "randomize" in kw and not isinstance(kw["randomize"], Randomization):
            kw["randomize"] = Randomization({k: tuple(v) for k, v in kw["randomize"].items()})
        return cls(**kw)

    def to_dict(self) -> dict[str, Any]:
        """The ``[task]`` table of an env TOML that :meth:`from_dict` turns back into this task.

        Returns
        -------
        dict
            ``trajectories`` (ids, or ``{"id": ..., **params}`` tables), ``action``,
            ``action_scale``, ``observation`` and ``reward`` (every field), ``randomize``
            (``{parameter: [low, high]}``).
        """
        return {
            "trajectories": [c.id if not c.params else {"id": c.id, **c.params}
                             for c in self.trajectories],
            "action": self.action,
            "action_scale": self.action_scale,
            "observation": asdict(self.observation),
            "reward": asdict(self.reward),
            "randomize": {k: [lo, hi] for k, (lo, hi) in self.randomize.ranges.items()},
        }


@lru_cache(maxsize=64)
def _cached_reference(id: str, items: tuple[tuple[str, Any], ...], ts: float) -> Reference:
    return make_trajectory(id, ts=ts, **dict(items))


REFERENCE_BYTES_PER_SAMPLE = 96
"""Estimated bytes per reference sample while it is generated and held by an env: the
reference's ``t, x, v, a``, the env's ``x, v, a`` tables and the generator's temporaries (the
vector env's float32 table of scaled features, 12 B, is built once those temporaries are
gone)."""


MAX_EPISODE_SAMPLES = 1_000_000
"""Longest reference of one episode, samples (1000 s at 1 kHz), as for an env spec's set."""


def reference_for(choice: TrajectoryChoice, ts: float, rng: np.random.Generator) -> Reference:
    """Generate (or fetch from cache) the reference of ``choice`` sampled at ``ts``.

    A ``duration`` parameter is checked first: at most :data:`MAX_EPISODE_SAMPLES` samples,
    and within the available memory (:data:`REFERENCE_BYTES_PER_SAMPLE`); ``ValueError``
    naming it and the figure.
    """
    duration = choice.params.get("duration")
    if isinstance(duration, (int, float)) and not isinstance(duration, bool) \
            and math.isfinite(duration) and duration > 0.0 and ts > 0.0:
        samples = math.ceil(duration / ts) + 1
        check_memory(f"trajectory {choice.id!r} duration={duration!r} s",
                     samples * REFERENCE_BYTES_PER_SAMPLE,
                     f"{samples} samples at ts={ts:g} s, {REFERENCE_BYTES_PER_SAMPLE} B each",
                     lambda room: f"duration <= {room / REFERENCE_BYTES_PER_SAMPLE * ts:.3g} s "
                                  "here")
        if samples > MAX_EPISODE_SAMPLES:
            # the trajectory generators slow down far more than linearly on very long runs
            raise ValueError(f"trajectory {choice.id!r} duration={duration!r} s: {samples} "
                             f"samples at ts={ts:g} s; expected at most {MAX_EPISODE_SAMPLES} "
                             f"({MAX_EPISODE_SAMPLES * ts:g} s: MAX_EPISODE_SAMPLES) per episode")
    params = dict(choice.params)
    if choice.seeded:
        params["seed"] = int(rng.integers(0, 2**31 - 1))
    items = tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in params.items()))
    return _cached_reference(choice.id, items, float(ts))


def n_features(cfg: ObservationConfig) -> int:
    """Features per axis: error, x_ref, v_ref, a_ref, measured v, previous action, motor force,
    preview."""
    return N_BASE_FEATURES + 2 * cfg.preview


N_BASE_FEATURES = 7
FEATURES = ("error", "x_ref", "v_ref", "a_ref", "v_meas", "prev_action", "motor_force")


def preview_offsets(cfg: ObservationConfig) -> np.ndarray:
    """Sample offsets of the preview points, shape (preview,)."""
    return cfg.preview_stride * np.arange(1, cfg.preview + 1)


@numba.njit(cache=True, inline="always")
def observe_row(r: int, S: np.ndarray, p: np.ndarray, X: np.ndarray, V: np.ndarray,
                A: np.ndarray, i: int, kk: int, offsets: np.ndarray, prev_action: float,
                inv: np.ndarray, out: np.ndarray) -> None:
    """Fill ``out[r]`` with the scaled observation of axis ``r`` of ``S`` (parameter row ``p``,
    ``P[r]`` or a row equal to it) following reference row ``i`` of the tables ``X, V, A`` at
    sample ``kk`` (the layout of :func:`fill_observation`; ``inv`` holds the reciprocals of the
    scales, so the row costs no division). The native vector env's step writes the same row
    with the same arithmetic, its reference features copied from a table
    (:func:`fricbench.gym.vector_step.vector_step`; tests/gym/test_vector.py pins the two equal).
    """
    n_prev = offsets.shape[0]
    inv_e, inv_x, inv_v, inv_a, inv_f = inv[0], inv[1], inv[2], inv[3], inv[4]
    # e = x_ref[k] - x_meas[k]
    out[r, 0] = (X[i, kk] - S[r, S_XMEAS]) * inv_e
    out[r, 1] = X[i, kk] * inv_x
    out[r, 2] = V[i, kk] * inv_v
    out[r, 3] = A[i, kk] * inv_a
    # measured velocity (x_fb[k] - x_fb[k-1]) / Ts
    out[r, 4] = (S[r, S_XFB] - S[r, S_XFB_PREV]) / p[P_TS] * inv_v
    out[r, 5] = prev_action
    out[r, 6] = p[P_KT] * S[r, S_IAPP] * inv_f
    for j in range(n_prev):
        o = kk + offsets[j]
        out[r, 7 + j] = V[i, o] * inv_v
        out[r, 7 + n_prev + j] = A[i, o] * inv_a


@numba.njit(cache=True)
def fill_observation(S: np.ndarray, P: np.ndarray, X: np.ndarray, V: np.ndarray, A: np.ndarray,
                     rows: np.ndarray, k: np.ndarray, offsets: np.ndarray,
                     prev_action: np.ndarray, scales: np.ndarray, out: np.ndarray) -> None:
    """Fill ``out`` (R, n_features) with the scaled observation of the R axes of ``S``.

    Axis ``r`` follows reference row ``rows[r]`` of the tables ``X, V, A`` at sample ``k[r]``.
    Columns: ``e/e_s, x_r/x_s, v_r/v_s, a_r/a_s, v_meas/v_s, a_prev, F_motor/F_s``, then the
    preview ``v_r[k+o]/v_s`` and ``a_r[k+o]/a_s`` for each offset ``o``. ``scales`` holds
    ``(e_s, x_s, v_s, a_s, F_s)``; ``F_motor = kt i`` is the force of the last sample (drives
    report their current).
    """
    inv = 1.0 / scales
    for r in range(S.shape[0]):
        observe_row(r, S, P[r], X, V, A, rows[r], k[r], offsets, prev_action[r], inv, out)


def obs_scales(cfg: ObservationConfig) -> np.ndarray:
    """The ``scales`` argument of :func:`fill_observation`."""
    return np.array([cfg.error_scale, cfg.position_scale, cfg.velocity_scale,
                     cfg.acceleration_scale, cfg.force_scale])


@numba.njit(cache=True)
def apply_action(action: np.ndarray, scale: float, out: np.ndarray) -> bool:
    """Clip ``action`` to [-1, 1] in place and write ``action * scale`` to ``out[:, 0]``;
    return False (writing nothing) if any entry is NaN or inf."""
    for i in range(action.shape[0]):
        if not math.isfinite(action[i]):
            return False
    for i in range(action.shape[0]):
        a = min(1.0, max(-1.0, action[i]))
        action[i] = a
        out[i, 0] = a * scale
    return True


def action_array(action: Any, shape: tuple[int, ...], name: str = "action",
                 also: tuple[tuple[int, ...], ...] = ()) -> np.ndarray:
    """``action`` as a float64 array of ``shape`` (finiteness is not checked here).

    Real numbers only (float, int): strings, complex, boolean and object values raise
    ``TypeError``; a shape other than ``shape`` or one of ``also`` raises ``ValueError``.
    """
    expected = "shape " + " or ".join("a plain number" if s == () else str(s)
                                      for s in (shape, *also))
    if isinstance(action, (str, bytes)):
        raise TypeError(f"{name}={action!r} ({type(action).__name__}): expected real numbers, "
                        f"{expected}")
    try:
        a = np.asarray(action)
    except (TypeError, ValueError):  # ragged nested sequences
        raise ValueError(f"{name}: a {type(action).__name__} that is not a rectangular array of "
                         f"numbers; expected {expected}") from None
    if a.dtype.kind not in "fiu":
        raise TypeError(f"{name} has dtype {a.dtype} ({type(action).__name__}): expected real "
                        f"numbers (float), {expected}")
    if a.shape != shape and a.shape not in also:
        raise ValueError(f"{name} has shape {a.shape}: expected {expected}")
    return a.astype(np.float64).reshape(shape)


def check_action(action: Any, shape: tuple[int, ...],
                 also: tuple[tuple[int, ...], ...] = ()) -> np.ndarray:
    """Validate an action (:func:`action_array`): NaN/inf raise ``ValueError``; out-of-range
    values are clipped."""
    a = action_array(action, shape, also=also)
    if not np.isfinite(a).all():
        raise ValueError(f"action={np.asarray(action)!r}: contains NaN or inf")
    return np.clip(a, -1.0, 1.0)


def stack_references(refs: Sequence[Reference], pad: int) -> tuple[np.ndarray, ...]:
    """Pad references to a common length (holding the last value) for vectorised look-up."""
    length = max(r.n_samples for r in refs) + pad + 1
    arrs = []
    for key in ("x", "v", "a"):
        table = np.empty((len(refs), length))
        for i, r in enumerate(refs):
            vals = getattr(r, key)
            table[i, : r.n_samples] = vals
            table[i, r.n_samples:] = vals[-1] if key == "x" else 0.0
        arrs.append(table)
    lengths = np.array([r.n_samples for r in refs], dtype=np.int64)
    return arrs[0], arrs[1], arrs[2], lengths
