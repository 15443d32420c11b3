"""An effort-driven rigid axis with stick-slip friction, integrated here for the open-loop
tests (independent of the package's plant): semi-implicit Euler with exact sticking."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

TS = 1e-3
"""Sample time of the runs, s."""


def multisine(n: int, rng: np.random.Generator, amp: float, period_s: float) -> np.ndarray:
    """Zero-mean multisine, periodic with ``period_s``, random phases."""
    t = np.arange(n) * TS
    f0 = 1.0 / period_s
    u = np.zeros(n)
    for k in range(1, 8):
        u += np.sin(2 * np.pi * k * f0 * t + rng.uniform(0, 2 * np.pi)) / k
    return amp * u / np.max(np.abs(u))


def simulate_axis(u: np.ndarray, m: float, b: float, fc: float, fs: float, vs: float,
                  f0: float, n_sub: int = 10,
                  ripple: Callable[[float], float] | None = None) -> np.ndarray:
    """M dv/dt = u - B v - sgn(v) (fc + (fs - fc) exp(-(v / vs)^2)) - f0 - ripple(x): sticks
    exactly (up to fs); while sliding the level is taken at the substep's starting speed."""
    h = TS / n_sub
    x = v = 0.0
    out = np.empty(u.size)
    for k in range(u.size):
        out[k] = x
        for _ in range(n_sub):
            force = u[k] - f0 - (ripple(x) if ripple is not None else 0.0)
            # v* = (M v + h force) / (M + h B); stick when |v*| <= h fs / (M + h B)
            den = m + h * b
            v_star = (m * v + h * force) / den
            if abs(v_star) <= h * fs / den:
                v_new = 0.0
            else:
                level = fc + (fs - fc) * np.exp(-((v / vs) ** 2))
                v_new = v_star - np.sign(v_star) * h * level / den
                if v_new * v_star < 0.0:
                    v_new = 0.0
            x += 0.5 * h * (v + v_new)
            v = v_new
    return out
