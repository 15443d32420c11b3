"""The diagnosis's verdict and what an unexplained residual looks like.

Three verdicts (the report's top-level ``verdict``):

* ``explained``: effects were added and the held-out position error fell by more than
  ``settings.heldout_gain`` (the validation run's when there is one, else the training run's free
  run, which the effort-judged search never fits);
* ``nothing_to_explain``: no effect was needed, the position residual is at the noise floor
  of a free-run prediction;
* ``not_explained``: a residual well above the floor that no candidate explains. The residual
  is then described by the simplest structure that carries most of it (:func:`describe`): a
  drift in time, a term that follows the position, a lag behind the motion (a delay), or a
  narrow peak of its spectrum (a resonance). A line of the sensor (mains hum,
  :func:`fricbench.sysid.diagnose.signals.sensor_lines`) is no structure of the axis: it is
  removed before, and never named a resonance.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import signal

from fricbench.sysid.diagnose.settings import defaults
from fricbench.sysid.diagnose.signals import remove_lines

__all__ = ["Verdict", "describe", "judge"]


@dataclass(frozen=True)
class Verdict:
    """The verdict of a diagnosis.

    Attributes
    ----------
    verdict : str
        ``"explained"``, ``"nothing_to_explain"`` or ``"not_explained"``.
    reason : str
        One sentence: why.
    residual : str
        What the remaining residual looks like (``"at the noise floor"`` or a structure).
    """

    verdict: str
    reason: str
    residual: str

    def to_dict(self) -> dict[str, str]:
        """JSON-ready form."""
        return {"verdict": self.verdict, "reason": self.reason, "residual": self.residual}


def _share(r: np.ndarray, fitted: np.ndarray) -> float:
    """Share of the variance of ``r`` carried by ``fitted``."""
    var = float(np.var(r))
    return 0.0 if var <= 0.0 else float(max(0.0, 1.0 - np.var(r - fitted) / var))


def _lstsq_fit(cols: np.ndarray, r: np.ndarray) -> np.ndarray:
    coef, *_ = np.linalg.lstsq(cols, r, rcond=None)
    return np.asarray(cols @ coef)


def describe(r: np.ndarray, x: np.ndarray, v_ref: np.ndarray, ts: float,
             unit: str = "m", lines: Sequence[float] = ()) -> str:
    """What the residual ``r`` of a free-run prediction looks like, in words.

    Each structure is fitted by least squares and its share of the residual's variance
    compared; the largest share wins when it exceeds ``settings.explained_share``:

    * a drift: a cubic polynomial in time;
    * a lag: the reference velocity and its derivative (``r ~ -tau v``: a delay ``tau``);
    * a position dependence: the residual averaged in 64 bins of the position;
    * a resonance: a peak of the Welch spectrum at least 20 times its median level, the
      residual band-passed around it (+-10 %).

    The sensor's lines (``lines``) are no structure of the axis: their least-squares
    sinusoids are removed from ``r`` first, and no peak within ``settings.mains_tolerance`` of
    one of them (or within two bins of the Welch spectrum) is named a resonance.

    Parameters
    ----------
    r : ndarray, shape (K,)
        Measured minus predicted position.
    x : ndarray, shape (K,)
        Measured position.
    v_ref : ndarray, shape (K,)
        Reference velocity.
    ts : float
        Sample time, s.
    unit : str
        Position unit of ``r`` (for the delay's wording).
    lines : sequence of float
        Frequencies (Hz) of the sensor's lines (mains hum) found in the measurement.

    Returns
    -------
    str
    """
    n = r.shape[0]
    if n < 16 or not np.all(np.isfinite(r)) or float(np.var(r)) <= 0.0:
        return "no structure (constant residual)"
    lines = [float(f) for f in lines]
    r = remove_lines(r, ts, lines)
    if float(np.var(r)) <= 0.0:
        return "no structure (constant residual)"
    r = r - float(np.mean(r))
    t = np.linspace(-1.0, 1.0, n)
    shares: dict[str, tuple[float, str]] = {}
    drift = _lstsq_fit(np.column_stack([np.ones(n), t, t**2, t**3]), r)
    shares["drift"] = (_share(r, drift), "a drift in time (a slow trend: thermal growth, a "
                                         "creeping offset)")
    a_ref = np.gradient(v_ref, ts)
    if np.ptp(v_ref) > 0.0:
        cols = np.column_stack([np.ones(n), v_ref, a_ref])
        coef, *_ = np.linalg.lstsq(cols, r, rcond=None)
        lag = _share(r, cols @ coef)
        tau = -float(coef[1])
        shares["lag"] = (lag, f"a lag behind the motion (the residual follows the reference "
                              f"velocity: a delay or a slower loop of about {1e3 * tau:.3g} ms)")
    if np.ptp(x) > 0.0:
        bins = np.minimum(((x - x.min()) / np.ptp(x) * 64).astype(np.int64), 63)
        counts = np.bincount(bins, minlength=64)
        means = np.bincount(bins, weights=r, minlength=64) / np.maximum(counts, 1)
        # a bin with few samples would fit noise: only bins with 1 % of the samples count
        fitted = np.where(counts[bins] >= 0.01 * n, means[bins], 0.0)
        shares["position"] = (_share(r, fitted), "a term that follows the position (a "
                                                 "periodic force or friction varying along "
                                                 "the stroke)")
    if n >= 256:
        f, pxx = signal.welch(r, fs=1.0 / ts, nperseg=min(n, 1024))
        if lines:
            # a sensor's line is no resonance of the axis, whatever is left of it
            near = np.zeros(f.size, dtype=bool)
            for fl in lines:
                near |= np.abs(f - fl) <= max(defaults().mains_tolerance * fl, 2.0 * f[1])
            pxx = np.where(near, 0.0, pxx)
        if pxx.size > 8:
            k = int(np.argmax(pxx[1:])) + 1
            peak = float(pxx[k] / max(float(np.median(pxx[1:])), 1e-300))
            if peak >= 20.0 and f[k] > 0.0:
                lo, hi = 0.9 * f[k], min(1.1 * f[k], 0.49 / ts)
                if hi > lo:
                    sos = signal.butter(2, [lo, hi], btype="bandpass", fs=1.0 / ts,
                                        output="sos")
                    band = signal.sosfiltfilt(sos, r)
                    shares["resonance"] = (_share(r, band), f"an oscillation near "
                                                            f"{f[k]:.3g} Hz (a resonance)")
    best = max(shares.values(), key=lambda s: s[0])
    if best[0] >= defaults().explained_share:
        return f"{best[1]}: {100 * best[0]:.0f} % of its variance"
    return (f"no dominant structure (the best, {best[1].split(' (')[0]}, carries "
            f"{100 * best[0]:.0f} % of its variance)")


def judge(effects: list[str], rms_after: float, floor: float, residual: np.ndarray,
          x: np.ndarray, v_ref: np.ndarray, ts: float, *,
          heldout: tuple[float, float] | None = None, heldout_name: str = "training",
          length: Callable[[float], str] | None = None,
          lines: Sequence[float] = ()) -> Verdict:
    """The verdict of a diagnosis (see the module docstring).

    Parameters
    ----------
    effects : list of str
        Effects added.
    rms_after : float
        Position rms of the final model on the training run.
    floor : float
        Noise floor of a free-run prediction (> 0).
    residual, x, v_ref : ndarray
        Final residual, measured position and reference velocity of the training run.
    ts : float
        Sample time, s.
    heldout : (float, float), optional
        Held-out position rms before and after (the validation run's).
    heldout_name : str
        Which run ``heldout`` is from.
    length : callable, optional
        Formats a position figure (SI) in the log's unit (default: ``"%.4g m"``).
    lines : sequence of float
        Frequencies (Hz) of the sensor's lines (:func:`describe`); their power is in
        ``floor`` already.
    """
    length = length or (lambda v: f"{v:.4g} m")
    at_floor = rms_after <= defaults().floor_factor * floor
    looks = "at the noise floor" if at_floor else describe(residual, x, v_ref, ts,
                                                                 lines=lines)
    if effects:
        before, after = heldout if heldout is not None else (float("nan"), float("nan"))
        if heldout is None or after < (1.0 - defaults().heldout_gain) * before:
            where = f"the {heldout_name} run's" if heldout is not None else "the"
            return Verdict("explained", f"{', '.join(effects)} added; {where} held-out "
                                        "position error fell", looks)
        return Verdict("not_explained", f"{', '.join(effects)} added on the training run, "
                                        f"but the {heldout_name} run's position error did not "
                                        f"fall by more than {100 * defaults().heldout_gain:.0f} % "
                                        f"({length(before)} -> {length(after)})", looks)
    if at_floor:
        return Verdict("nothing_to_explain", "the linear model's position residual is at the "
                                             "noise floor of a free-run prediction", looks)
    return Verdict("not_explained", "a residual well above the noise floor that no candidate "
                                    "effect explains", looks)
