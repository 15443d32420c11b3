"""Argument checks shared by every constructor: each error names the parameter, value and need."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = [
    "check_choice",
    "check_finite",
    "check_int",
    "check_nonneg",
    "check_positive",
    "check_range",
    "check_signal",
]


def check_finite(name: str, value: Any) -> float:
    """Return ``value`` as float; raise if it is not a finite real number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) and not hasattr(
        value, "__float__"
    ):
        raise TypeError(f"{name}={value!r}: expected a real number")
    out = float(value)
    if not math.isfinite(out):
        raise ValueError(f"{name}={value!r}: expected a finite number")
    return out


def check_positive(name: str, value: Any, unit: str = "") -> float:
    """Finite and ``> 0``."""
    out = check_finite(name, value)
    if out <= 0.0:
        raise ValueError(f"{name}={value!r}: expected > 0{' ' + unit if unit else ''}")
    return out


def check_nonneg(name: str, value: Any, unit: str = "") -> float:
    """Finite and ``>= 0``."""
    out = check_finite(name, value)
    if out < 0.0:
        raise ValueError(f"{name}={value!r}: expected >= 0{' ' + unit if unit else ''}")
    return out


def check_range(name: str, value: Any, lo: float, hi: float, unit: str = "") -> float:
    """Finite and within ``[lo, hi]``."""
    out = check_finite(name, value)
    if not lo <= out <= hi:
        raise ValueError(
            f"{name}={value!r}: expected a value in [{lo:g}, {hi:g}]{' ' + unit if unit else ''}"
        )
    return out


def check_int(name: str, value: Any, lo: int, hi: int | None = None) -> int:
    """An integer (not bool) in ``[lo, hi]``."""
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise TypeError(f"{name}={value!r}: expected an integer")
    if value < lo or (hi is not None and value > hi):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise ValueError(f"{name}={value!r}: expected an integer {rng}")
    return int(value)


def check_choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    """One of ``choices``."""
    if value not in choices:
        raise ValueError(f"{name}={value!r}: expected one of {', '.join(map(repr, choices))}")
    return str(value)


def check_signal(name: str, value: Any) -> np.ndarray:
    """``value`` as a 1-D float array of finite samples."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"{name} has shape {arr.shape}: expected a 1-D array of samples")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ValueError(f"{name} contains NaN or inf (first at sample {int(bad[0])})")
    return arr
