"""Scores of one run: max/RMS tracking error, reversal peaks, circular deviation, effort."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fricbench.run_events import motion_sign, sign_reversals

__all__ = ["REVERSAL_WINDOW_S", "RunMetrics", "contour_error", "reversal_indices", "score_run"]

REVERSAL_WINDOW_S = 0.05  # s: the window after a reversal in which its peak error is taken


@dataclass(frozen=True)
class RunMetrics:
    """Scores in SI units (m, N); ``circular_deviation`` and ``reversal_spike`` only for
    two-axis contouring runs (NaN otherwise)."""

    max_error: float
    rms_error: float
    reversal_peak: float
    effort_rms: float
    circular_deviation: float = float("nan")
    reversal_spike: float = float("nan")


def reversal_indices(v_ref: np.ndarray, ts: float, rest_speed: float = 1e-6) -> np.ndarray:
    """Samples where the reference velocity changes sign (direct or after a dwell).

    A reversal after a stop is placed where motion resumes in the opposite direction
    (:func:`fricbench.run_events.sign_reversals`; ``ts`` is not used).
    """
    return sign_reversals(motion_sign(v_ref, rest_speed))


def _peak_after(err: np.ndarray, marks: np.ndarray, window: int) -> float:
    if marks.size == 0:
        return float("nan")
    peaks = [np.max(np.abs(err[max(0, m - window // 5): m + window])) for m in marks]
    return float(np.max(peaks))


def contour_error(err: np.ndarray, v_ref: np.ndarray) -> np.ndarray:
    """Contour error of a two-axis run: the tracking error normal to the path, m.

    ``err`` and ``v_ref`` have shape (2, K). Where the reference stands still the whole error
    magnitude is taken (no path direction).
    """
    speed = np.hypot(v_ref[0], v_ref[1])
    safe = np.where(speed > 1e-9, speed, 1.0)
    # e_c = e x t: error component normal to the path
    return np.where(speed > 1e-9, (err[0] * v_ref[1] - err[1] * v_ref[0]) / safe,
                    np.hypot(err[0], err[1]))


def score_run(t: np.ndarray, x_ref: np.ndarray, x_true: np.ndarray, v_ref: np.ndarray,
              effort: np.ndarray) -> RunMetrics:
    """Score a run; arrays are (K,) for one axis or (D, K) for contouring.

    ``effort`` is the compensation (N or m, as the compensator acts). For two axes the
    tracking error is the contour error (normal to the path), the circular deviation is the
    ISO 230-4 radial range ``max r - min r`` about the reference circle's centre, and the
    reversal spike is the largest radial deviation within 50 ms of an axis reversal, measured
    from the median radial deviation.
    """
    ts = float(t[1] - t[0])
    window = max(1, int(round(REVERSAL_WINDOW_S / ts)))
    effort_rms = float(np.sqrt(np.mean(np.square(effort))))
    if np.ndim(x_ref) == 1:
        err = x_ref - x_true
        marks = reversal_indices(v_ref, ts)
        return RunMetrics(float(np.max(np.abs(err))), float(np.sqrt(np.mean(err**2))),
                          _peak_after(err, marks, window), effort_rms)
    err = x_ref - x_true
    speed = np.hypot(v_ref[0], v_ref[1])
    contour = contour_error(err, v_ref)
    centre = 0.5 * (x_ref.max(axis=1) + x_ref.min(axis=1))
    r_ref = np.hypot(x_ref[0] - centre[0], x_ref[1] - centre[1])
    r_act = np.hypot(x_true[0] - centre[0], x_true[1] - centre[1])
    moving = speed > 1e-6
    radial = (r_act - r_ref)[moving] if moving.any() else r_act - r_ref
    circ_dev = float(np.max(radial) - np.min(radial))
    marks = np.concatenate([reversal_indices(v_ref[i], ts) for i in range(v_ref.shape[0])])
    dev = (r_act - r_ref) - np.median(radial)
    spike = _peak_after(dev, np.sort(marks), window)
    return RunMetrics(float(np.max(np.abs(contour))), float(np.sqrt(np.mean(contour**2))),
                      _peak_after(contour, np.sort(marks), window), effort_rms, circ_dev, spike)
