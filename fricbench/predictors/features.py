"""Input features computed from a sampled reference position alone.

Every predictor derives its inputs here, from the reference positions and the sample time, in
training and in prediction alike (velocity and acceleration by central differences, as the
paper does), so that a prediction never depends on how a reference was generated.

Two feature sets:

``"va"`` (the paper, Sec. 3.2)
    Reference velocity and acceleration. The velocity enters twice: scaled by its standard
    deviation, and as ``tanh(v / v_break)``, which resolves the pre-sliding range
    ``|v| < v_break`` that a linear scaling squeezes into a few hundredths.
``"physical"`` (improved predictors)
    The ``"va"`` columns plus what a stick-slip cycle depends on: the direction of the last
    motion, whether the last turning point (start or reversal) kept or reversed the direction
    (or was the first start of the run), the time and the reference displacement since it, the
    reference acceleration at that turning point (the paper's ``a0``), the time
    since the reference was last at rest, and the time to the next turning point or stop (the
    reference is known in advance, so this look-ahead is available to a feedforward).
"""

from __future__ import annotations

import numpy as np

from fricbench.run_events import motion_events, motion_sign
from fricbench.sysid.friction_error import reference_velocity

__all__ = ["FEATURE_SETS", "feature_names", "reference_features"]

FEATURE_SETS = ("va", "physical")

_NAMES = {
    "va": ("v", "a", "tanh_v_vbreak"),
    "physical": ("v", "a", "tanh_v_vbreak", "direction", "turn_kind", "time_since_turn",
                 "disp_since_turn", "a_at_turn", "time_since_rest", "time_to_next"),
}

_V_TOL = 1e-6  # m/s: below this the reference is at rest (fricbench.run_events)


def feature_names(feature_set: str) -> tuple[str, ...]:
    """Column names of ``feature_set``."""
    if feature_set not in _NAMES:
        raise ValueError(f"features={feature_set!r}: expected one of {FEATURE_SETS}")
    return _NAMES[feature_set]


def _last_true(flag: np.ndarray) -> np.ndarray:
    """For each sample, the index of the latest ``True`` at or before it (``-1`` if none)."""
    idx = np.where(flag, np.arange(flag.shape[0]), -1)
    return np.maximum.accumulate(idx)


def _next_true(flag: np.ndarray) -> np.ndarray:
    """For each sample, the index of the next ``True`` at or after it (``K`` if none)."""
    k = flag.shape[0]
    idx = np.where(flag, np.arange(k), k)
    return np.minimum.accumulate(idx[::-1])[::-1]


def reference_features(x_ref: np.ndarray, ts: float, feature_set: str, v_break: float, *,
                       horizon: float = 0.3, disp_max: float = 1e-3) -> np.ndarray:
    """Feature matrix of a reference, shape (K, F), SI units (not yet normalised).

    Parameters
    ----------
    x_ref : ndarray, shape (K,)
        Reference position, m.
    ts : float
        Sample time, s.
    feature_set : {"va", "physical"}
        See the module docstring.
    v_break : float
        Break velocity, m/s (scale of the ``tanh`` velocity column).
    horizon : float, optional
        Time features saturate at this value, s.
    disp_max : float, optional
        The displacement feature saturates at this value, m.
    """
    names = feature_names(feature_set)
    v, a = reference_velocity(x_ref, ts)
    cols = [v, a, np.tanh(v / v_break)]
    if feature_set == "physical":
        k = np.arange(v.shape[0])
        sgn = motion_sign(v, _V_TOL)
        moving = sgn != 0.0
        last_move = _last_true(moving)
        direction = np.where(last_move >= 0, sgn[np.maximum(last_move, 0)], 0.0)
        prev_dir = np.concatenate([[0.0], direction[:-1]])
        # turning point: motion begins after rest (any rest: max_gap=0), or the direction of
        # motion changes; at the first moving sample
        turn = np.zeros(v.shape[0], dtype=bool)
        turn[[e.onset for e in motion_events(v, ts, rest_speed=_V_TOL, max_gap=0)
              if e.kind != "stop"]] = True
        last_turn = _last_true(turn)
        j = np.maximum(last_turn, 0)
        seen = last_turn >= 0
        time_since_turn = np.where(seen, (k - last_turn) * ts, horizon)
        disp = np.where(seen, np.abs(x_ref - x_ref[j]), disp_max)
        a_turn = np.where(seen, a[j] * direction, 0.0)
        # +1: the motion resumed in the direction it had before the last turning point (a start
        # after a stop), -1: it reversed, 0: the first motion of the run
        before = np.where(j > 0, prev_dir[j], 0.0)
        turn_kind = np.where(seen, before * direction, 0.0)
        last_rest = _last_true(~moving)
        time_since_rest = np.where(last_rest >= 0, (k - last_rest) * ts, horizon)
        nxt = _next_true(turn | ~moving)
        time_to_next = np.where(nxt < v.shape[0], (nxt - k) * ts, horizon)
        cols += [direction, turn_kind, np.minimum(time_since_turn, horizon),
                 np.minimum(disp, disp_max),
                 a_turn, np.minimum(time_since_rest, horizon), np.minimum(time_to_next, horizon)]
    out = np.column_stack(cols)
    if out.shape[1] != len(names):  # pragma: no cover - guards the table above
        raise RuntimeError("feature table out of sync")
    return out
