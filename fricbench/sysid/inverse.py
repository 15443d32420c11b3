"""Non-causal stable inversion of a sampled loop: what ILC and model-inverse pre-compensation
share.

A whole reference is known before it runs, so a correction ``u`` that makes a linear path
``P`` produce a wanted signal ``e`` can be computed over the whole trial at once::

    u = Q( L e ),   L(e^{jw}) = conj(P) / (|P|^2 + beta max|P|^2)

``L`` is a regularised inverse of ``P`` applied by FFT (zero-padded: no wrap-around), ``Q`` a
zero-phase Butterworth low-pass (``scipy.signal.filtfilt``) that keeps the correction to the
band where the model is trusted.
"""

from __future__ import annotations

import control
import numpy as np
from scipy import signal

from fricbench._validation import check_int, check_positive

__all__ = ["inverse_gain", "pulse_response", "stable_inverse", "zero_phase_lowpass"]


def pulse_response(g: control.TransferFunction, ts: float, n: int = 3000) -> np.ndarray:
    """Response ``h[k]`` of the zero-order-hold sampled ``g`` to a unit pulse (sum = DC gain).

    Raises
    ------
    ValueError
        The response has not decayed within ``n`` samples (unstable or very slow ``g``).
    """
    check_positive("ts", ts, "s")
    check_int("n", n, 16, 10_000_000)
    gd = control.sample_system(g, ts, method="zoh")
    _, step = control.step_response(gd, T=np.arange(n) * ts)
    h = np.diff(np.concatenate([[0.0], np.ravel(step)]))
    if not np.all(np.isfinite(h)) or np.max(np.abs(h[-n // 10:])) > 1e-3 * np.max(np.abs(h)):
        raise ValueError(f"the pulse response of {g} has not decayed within n={n} samples: "
                         "expected a stable, well-damped loop")
    return h


def inverse_gain(h: np.ndarray, n_fft: int, beta: float) -> np.ndarray:
    """``L = conj(P) / (|P|^2 + beta max|P|^2)`` on the ``rfft`` grid of ``n_fft`` points."""
    check_positive("beta", beta)
    p = np.fft.rfft(h, n_fft)
    return np.conj(p) / (np.abs(p) ** 2 + beta * np.max(np.abs(p)) ** 2)


def zero_phase_lowpass(x: np.ndarray, cutoff: float, ts: float, order: int = 2) -> np.ndarray:
    """Butterworth low-pass of ``order`` run forwards and backwards along the last axis."""
    check_positive("cutoff", cutoff, "Hz")
    if cutoff >= 0.5 / ts:
        raise ValueError(f"cutoff={cutoff:g} Hz: expected below the Nyquist frequency "
                         f"{0.5 / ts:g} Hz of ts={ts:g} s")
    b, a = signal.butter(order, cutoff, fs=1.0 / ts)
    pad = min(3 * max(len(a), len(b)), x.shape[-1] - 1)
    return signal.filtfilt(b, a, x, axis=-1, padlen=pad)


def stable_inverse(h: np.ndarray, e: np.ndarray, ts: float, *, beta: float = 1e-2,
                   cutoff: float = 100.0, order: int = 2) -> np.ndarray:
    """``u = Q(L e)``: the input that makes the path with pulse response ``h`` produce ``e``.

    Parameters
    ----------
    h : ndarray, shape (M,)
        Pulse response of the path (:func:`pulse_response`).
    e : ndarray, shape (K,) or (D, K)
        Wanted output over the trial.
    ts : float
        Sample time, s.
    beta : float
        Regularisation relative to ``max |P|^2``.
    cutoff : float
        Q-filter cutoff, Hz.
    order : int
        Butterworth order of one pass of the Q-filter.
    """
    e = np.asarray(e, dtype=float)
    k = e.shape[-1]
    n_fft = 1 << int(np.ceil(np.log2(k + h.size)))
    u = np.fft.irfft(inverse_gain(h, n_fft, beta) * np.fft.rfft(e, n_fft, axis=-1), n_fft,
                     axis=-1)[..., :k]
    return zero_phase_lowpass(u, cutoff, ts, order)
