"""Statistics of the leaderboards: medians over seeds with bootstrap intervals, paired tests.

Every interval is a 95 % percentile bootstrap (:func:`scipy.stats.bootstrap`) of the median over
seeds. Its generator is seeded from the benchmark seeds and a label of the cell
(:func:`cell_rng`), so the same rows give the same tables, bit for bit. Seeds share plants
(every compensator runs on the same drawn machine of a seed), so two compensators are compared
on their per-seed *differences* (:func:`paired_difference`), not on overlapping intervals. Two
compensators without a seed in common (rows merged from runs on other seeds) are compared by
:func:`unpaired_difference`, the difference of their medians, each resampled on its own: wider,
as it cannot remove the plants' spread, and said as such in the tables.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

__all__ = [
    "CONFIDENCE",
    "MIN_SEEDS",
    "N_RESAMPLES",
    "Interval",
    "cell_rng",
    "median_ci",
    "min_seeds",
    "paired_difference",
    "unpaired_difference",
]

CONFIDENCE = 0.95
N_RESAMPLES = 9999


def min_seeds(confidence: float = CONFIDENCE) -> int:
    """The fewest seeds whose percentile bootstrap interval of the median can hold the true
    median with probability ``confidence``.

    The interval never leaves the sample's range [min, max], and that range misses the
    median of a continuous distribution when every value falls on one side of it:
    P(min <= median <= max) = 1 - 2^(1 - n). Fewer seeds give an interval that claims
    ``confidence`` it cannot have (n = 2: 50 %, n = 5: 94 %).
    """
    n = 1
    # 1 - 2^(1 - n) >= confidence
    while 1.0 - 2.0 ** (1 - n) < confidence:
        n += 1
    return n


MIN_SEEDS = min_seeds(CONFIDENCE)
"""Fewest seeds whose 95 % interval can mean 95 % (6): below it the tables carry a caveat."""


@dataclass(frozen=True)
class Interval:
    """A median over seeds and its bootstrap interval.

    ``low``/``high`` are None when there are fewer than two finite values (no interval); with
    all values equal the interval is that value.
    """

    median: float
    low: float | None
    high: float | None
    n: int

    @property
    def has_ci(self) -> bool:
        return self.low is not None and self.high is not None

    def excludes_zero(self) -> bool:
        """Whether the interval lies wholly above or below 0 (False without an interval)."""
        return self.has_ci and (self.low > 0.0 or self.high < 0.0)  # type: ignore[operator]

    def text(self, fmt: str = ".2f", sign: bool = False) -> str:
        """``"12.34 [11.90, 12.80]"``; ``"12.34 (n=1)"`` without an interval."""
        f = ("+" if sign else "") + fmt
        if not self.has_ci:
            return f"{self.median:{f}} (n={self.n})"
        return f"{self.median:{f}} [{self.low:{f}}, {self.high:{f}}]"


def cell_rng(seeds: Sequence[int], *labels: str) -> np.random.Generator:
    """The bootstrap generator of one cell: seeded from the benchmark seeds and the labels.

    ``zlib.crc32`` (not ``hash``, which Python salts per process) turns the labels into
    integers, so that the generator is the same in every run.
    """
    words = [int(s) for s in sorted(seeds)] + [zlib.crc32(lab.encode()) for lab in labels]
    return np.random.default_rng(np.random.SeedSequence(words))


def median_ci(values: Sequence[float], rng: np.random.Generator,
              confidence: float = CONFIDENCE, n_resamples: int = N_RESAMPLES) -> Interval:
    """Median of the finite ``values`` and its percentile bootstrap interval.

    Raises
    ------
    ValueError
        If no value is finite.
    """
    x = np.asarray([v for v in values if math.isfinite(v)], dtype=float)
    if x.size == 0:
        raise ValueError("values: expected at least one finite number")
    med = float(np.median(x))
    if x.size < 2:
        return Interval(med, None, None, int(x.size))
    if np.all(x == x[0]):  # degenerate: every resample has the same median
        return Interval(med, med, med, int(x.size))
    res = stats.bootstrap((x,), np.median, confidence_level=confidence,
                          n_resamples=n_resamples, method="percentile", vectorized=True,
                          rng=rng)
    lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
    return Interval(med, lo, hi, int(x.size))


def paired_difference(a: dict[int, float], b: dict[int, float], rng: np.random.Generator,
                      confidence: float = CONFIDENCE) -> Interval | None:
    """Median over the seeds both have of ``a[s] - b[s]``, with its bootstrap interval.

    The difference is significant when :meth:`Interval.excludes_zero`. None when no seed has
    finite values in both.
    """
    common = sorted(s for s in a.keys() & b.keys()
                    if math.isfinite(a[s]) and math.isfinite(b[s]))
    if not common:
        return None
    return median_ci([a[s] - b[s] for s in common], rng, confidence)


def unpaired_difference(a: dict[int, float], b: dict[int, float], rng: np.random.Generator,
                        confidence: float = CONFIDENCE,
                        n_resamples: int = N_RESAMPLES) -> Interval | None:
    """``median(a) - median(b)`` over their own seeds, with a percentile bootstrap interval
    resampling ``a`` and ``b`` independently (for two sets of seeds with none in common).

    ``n`` is the smaller of the two counts; no interval when either has fewer than two finite
    values. None when either has none.
    """
    x = np.asarray([v for v in a.values() if math.isfinite(v)], dtype=float)
    y = np.asarray([v for v in b.values() if math.isfinite(v)], dtype=float)
    if x.size == 0 or y.size == 0:
        return None
    med = float(np.median(x) - np.median(y))
    n = int(min(x.size, y.size))
    if n < 2:
        return Interval(med, None, None, n)
    if np.all(x == x[0]) and np.all(y == y[0]):  # degenerate: every resample gives med
        return Interval(med, med, med, n)

    def diff(u: np.ndarray, v: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.asarray(np.median(u, axis=axis) - np.median(v, axis=axis))

    res = stats.bootstrap((x, y), diff, confidence_level=confidence, n_resamples=n_resamples,
                          method="percentile", vectorized=True, paired=False, rng=rng)
    lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
    return Interval(med, lo, hi, n)
