"""The diagnosis' one criterion, and the uncertainty of what it selects.

A model structure (the effects in it, and later the loop's) is judged by its **held-out
free-run error**: the run is cut into contiguous blocks, each simulated free (from its own first
samples) by the model fitted on the other blocks. Between two structures the one with the
smaller value of

    J = n_eff ln(SSE_heldout / n) + penalty k

wins, where ``k`` counts the fitted parameters, ``penalty`` is Akaike's 2 and ``n_eff`` is the
number of independent samples the residual is worth. It is Akaike's information criterion
(Akaike 1974; Ljung 1999, section 16.4; SysIdentPy's ``info_criteria="aic"``) with two
changes that a free-run error asks for:

- the error is the held-out one, so a structure that only fits the training samples' noise
  does not lower it (cross-validation, Ljung 1999, section 16.5);
- a free-run error is strongly correlated from sample to sample (a wrong friction level drifts
  the position for a whole move), so ``n`` samples are worth ``n_eff = n / tau`` independent
  ones, ``tau = 1 + 2 sum_k rho_k`` the residual's integrated autocorrelation time (the
  effective sample size of a correlated series, e.g. Bretherton et al. 1999, J. Climate 12).
  With ``n`` in its place, any structure would win on a long log by a hair's gain.

The parameter covariance of an output-error fit is ``s^2 (J^T J)^-1`` (Ljung 1999, eq. 9.18),
inflated by the same ``tau`` for a correlated residual.

**Detection**, one rule for the closed and the open loop: an effect whose every size (a gap, a
level, an amplitude; not a shape: a period, a time constant, a Stribeck velocity) lies within
``detection_sd`` standard deviations of zero is not detected (:func:`size_over_sd`,
:func:`least_detected`). The columns of the Jacobian kept in the covariance are those the
residual moves and that are not on a bound of their range (:func:`kept_columns`); the size is
tested with its effect's shape held at its fitted value, since a shape means nothing when the
size is zero (Davies 1977), and its standard deviation is that of its column projected off the
other kept columns (:func:`conditional_sd`). The standard deviations *reported* beside the
parameters stay the marginal ones (:func:`held_covariance`, every kept parameter free, the
shapes too): they say how well the value is known; the detection asks another question,
whether the size can be told from zero, under which the shape is not defined.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

__all__ = ["effective_samples", "comparison_samples", "criterion", "criterion_change",
           "false_detection_rate",
           "block_consistency",
           "parameter_covariance", "described_sd", "kept_columns", "held_covariance",
           "conditional_sd", "size_over_sd", "least_detected", "profile_statistic",
           "UNIDENTIFIED"]

UNIDENTIFIED = 1e100
"""Variance factor given to a direction of the parameters the data do not determine."""


def effective_samples(residual: np.ndarray, max_lag_share: float) -> float:
    """Independent samples a correlated residual is worth: ``n / tau``.

    ``tau = 1 + 2 sum_{k>=1} rho_k``, ``rho_k`` the residual's autocorrelation about zero (an
    offset is correlated, not noise), summed up to its first non-positive value and at most
    ``max_lag_share`` of the length. Between 1 and ``n``.
    """
    r = np.asarray(residual, dtype=float).ravel()
    r = r[np.isfinite(r)]
    n = r.size
    if n < 3:
        return float(max(n, 1))
    energy = float(np.dot(r, r))
    if energy <= 0.0:
        return float(n)
    size = 1 << (2 * n - 1).bit_length()
    spec = np.fft.rfft(r, size)
    # rho_k = sum_t r_t r_{t+k} / sum_t r_t^2
    rho = np.fft.irfft(spec * np.conj(spec), size)[:n] / energy
    max_lag = max(1, int(max_lag_share * n))
    lags = rho[1:max_lag + 1]
    stop = np.flatnonzero(lags <= 0.0)
    kept = lags[:stop[0]] if stop.size else lags
    tau = 1.0 + 2.0 * float(np.sum(kept))
    return float(min(max(n / tau, 1.0), n))


def comparison_samples(residual: np.ndarray, residual_other: np.ndarray, k: int, k_other: int,
                       max_lag_share: float) -> float:
    """The ``n_eff`` two structures fitted to the same run are compared with.

    That of the residual of the structure with more parameters: ``residual_other`` when
    ``k_other > k`` (and it is finite), else ``residual``. As the F-test takes the noise from
    the unrestricted model's residual: what the simpler structure misses is the question the
    comparison asks, and its correlation counted as the noise's would discount the very
    evidence against it (a drift the simpler model lacks makes its residual worth a handful
    of independent samples, whatever the richer one leaves).

    Parameters
    ----------
    residual, residual_other : ndarray
        Residuals of the two structures.
    k, k_other : int
        Their parameter counts.
    max_lag_share : float
        As in :func:`effective_samples`.
    """
    other = np.asarray(residual_other, dtype=float)
    if k_other > k and other.size and np.all(np.isfinite(other)):
        return effective_samples(other, max_lag_share)
    return effective_samples(residual, max_lag_share)


def criterion(sse: float, n: int, n_eff: float, k: int, penalty: float) -> float:
    """``J = n_eff ln(SSE / n) + penalty k`` (smaller is better; inf for a non-finite SSE)."""
    if not (math.isfinite(sse) and sse > 0.0 and n > 0):
        return math.inf if not (math.isfinite(sse) and sse >= 0.0) else -math.inf
    return n_eff * math.log(sse / n) + penalty * k


def criterion_change(sse_new: float, sse_old: float, k_new: int, k_old: int, n_eff: float,
                     penalty: float) -> float:
    """``J_new - J_old`` on the same held-out samples: negative when the new structure wins.

    ``n_eff ln(SSE_new / SSE_old) + penalty (k_new - k_old)``; inf when the new structure's
    error is not finite (it diverged on a held-out block: rejected, never ranked).
    """
    if not (math.isfinite(sse_new) and sse_new >= 0.0):
        return math.inf
    if not (math.isfinite(sse_old) and sse_old > 0.0):
        return -math.inf if math.isfinite(sse_new) else math.inf
    return n_eff * math.log(max(sse_new, 1e-300) / sse_old) + penalty * (k_new - k_old)


def false_detection_rate(detection_sd: float) -> float:
    """The detection rule's false-detection rate, ``2 Phi(-detection_sd)`` (4.6 % at 2 sd): how
    often a size within ``detection_sd`` standard deviations of zero, on either side, is taken
    for an effect. Every test that asks "is it there" (the block consistency, the one block
    left out) runs at this rate."""
    from scipy.stats import norm

    return float(2.0 * norm.sf(detection_sd))


def block_consistency(cand: np.ndarray, base: np.ndarray, left_out: int | None = None
                      ) -> float | None:
    """How likely chance alone makes a candidate's held-out cut as one-sided over the blocks.

    A true effect cuts the held-out error wherever it acts, and barely moves it elsewhere; a
    flexible effect that absorbs a misfit of the loop model trades blocks (better where the
    misfit sat, worse where its shape does not belong), which a sum of squared errors does
    not see. The one-sided Wilcoxon signed-rank test (Wilcoxon 1945; ``scipy.stats.wilcoxon``)
    of the per-block cuts ``base - cand`` asks whether they lean to one side: small cuts of
    blocks the effect does not touch rank low and weigh little. Blocks whose errors are equal
    (the effect does nothing there) and a block left out of the judgement
    (``search.block_left_out``) do not count.

    Parameters
    ----------
    cand, base : ndarray
        Squared held-out error per block of the candidate and of the model without it.
    left_out : int, optional
        A block left out of the judgement.

    Returns
    -------
    float or None
        The test's p-value (small: consistent), or None when fewer than 4 blocks differ (no
        test: the smallest p-value of 3 is 1/8).
    """
    from scipy.stats import wilcoxon

    diff = np.asarray(base, dtype=float) - np.asarray(cand, dtype=float)
    if left_out is not None:
        diff = np.delete(diff, left_out)
    diff = diff[np.isfinite(diff) & (diff != 0.0)]
    if diff.size < 4:
        return None
    return float(wilcoxon(diff, alternative="greater").pvalue)


def parameter_covariance(jac: np.ndarray, residual: np.ndarray, n_eff: float) -> np.ndarray:
    """Covariance of output-error estimates: ``tau s^2 (J^T J)^-1``.

    Parameters
    ----------
    jac : ndarray, shape (n, p)
        Jacobian of the residual at the optimum, in the parameters' units.
    residual : ndarray, shape (n,)
        The residual at the optimum.
    n_eff : float
        Independent samples the residual is worth (``tau = n / n_eff``).

    Returns
    -------
    ndarray, shape (p, p)
        A direction the data do not determine (a singular value below ``1e-10`` of the
        largest) gets a variance factor of :data:`UNIDENTIFIED` along it: so large that no
        effect along it is detected, and still a finite number.
    """
    jac = np.asarray(jac, dtype=float)
    r = np.asarray(residual, dtype=float).ravel()
    n, p = jac.shape
    if p == 0:
        return np.zeros((0, 0))
    dof = max(n - p, 1)
    s2 = float(np.dot(r, r)) / dof
    tau = n / max(n_eff, 1.0)
    _, sv, vt = np.linalg.svd(jac, full_matrices=False)
    inv = np.where(sv > 1e-10 * max(float(sv[0]), 1e-300), 1.0 / np.maximum(sv, 1e-300) ** 2,
                   UNIDENTIFIED)
    return tau * s2 * (vt.T * inv) @ vt


def described_sd(describe: Callable[[np.ndarray], Mapping[str, float]], row: np.ndarray,
                 idx: list[int], cov: np.ndarray, steps: np.ndarray) -> dict[str, float]:
    """Standard deviations of the described parameters (the delta method).

    ``describe(row)`` maps a plant row to named values (an amplitude from two components, a
    period); its derivatives along the free entries ``idx`` (forward differences of ``steps``)
    carry ``cov`` to them: ``var f = g^T C g``.
    """
    base = dict(describe(row))
    grads = {key: np.zeros(len(idx)) for key in base}
    for j, (i, h) in enumerate(zip(idx, steps, strict=True)):
        q = row.copy()
        q[i] += h
        moved = describe(q)
        for key in base:
            grads[key][j] = (moved[key] - base[key]) / h
    out = {}
    for key, g in grads.items():
        var = float(g @ cov @ g)
        if not math.isfinite(var):
            var = UNIDENTIFIED
        out[key] = math.sqrt(var) if var > 0.0 else 0.0
    return out


def kept_columns(jac: np.ndarray, held: np.ndarray) -> np.ndarray:
    """Columns of a Jacobian the covariance keeps: moved by the residual and not ``held``.

    Parameters
    ----------
    jac : ndarray, shape (n, p)
        Jacobian of the residual in the fit's own (scaled) coordinates, so that a column's
        norm compares with the others'.
    held : ndarray of bool, shape (p,)
        Columns on a bound of their range at the optimum: an active constraint, no free
        parameter there (a Stribeck velocity at its smallest).

    Returns
    -------
    ndarray of bool, shape (p,)
        False for a held column and for one the residual does not move (its norm below
        ``1e-10`` of the largest, :func:`parameter_covariance`'s own rank cut): such a
        parameter is held at its value and the others' covariance taken without it, so that
        rounding along its direction leaks into none of them.
    """
    norms = np.sqrt(np.sum(jac ** 2, axis=0))
    moved = norms > 1e-10 * max(float(np.max(norms, initial=0.0)), 1e-300)
    return moved & ~np.asarray(held, dtype=bool)


def held_covariance(jac: np.ndarray, residual: np.ndarray, n_eff: float, keep: np.ndarray
                    ) -> np.ndarray:
    """Covariance of every column of ``jac``, those not in ``keep`` held at their values
    (variance :data:`UNIDENTIFIED`, no covariance with the others).

    The marginal covariance of the kept parameters (:func:`parameter_covariance`, all of them
    free together): what the reported standard deviations are taken from."""
    p = jac.shape[1]
    cov = np.zeros((p, p))
    cov[np.diag_indices(p)] = UNIDENTIFIED
    kept = np.flatnonzero(keep)
    if kept.size:
        cov[np.ix_(kept, kept)] = parameter_covariance(jac[:, kept], residual, n_eff)
    return cov


def conditional_sd(jac: np.ndarray, residual: np.ndarray, n_eff: float, j: int,
                   keep: np.ndarray) -> float:
    """Standard deviation of column ``j``'s parameter, the other kept columns free.

    ``sqrt(tau s^2) / |P J_j|``, ``P`` the projection off the span of the other kept
    columns: the diagonal of ``tau s^2 (J^T J)^-1`` where that is invertible, and still right
    where the other columns are collinear among themselves (two loop gains the run cannot tell
    apart say nothing of a cogging's amplitude), which the inverse's regularised directions
    would leak into every parameter. Infinite when column ``j`` lies in their span.
    """
    n = jac.shape[0]
    others = np.flatnonzero(keep)
    others = others[others != j]
    target = jac[:, j]
    if others.size:
        a = jac[:, others]
        norms = np.sqrt(np.sum(a ** 2, axis=0))
        a = a / np.where(norms > 0.0, norms, 1.0)
        coef = np.linalg.lstsq(a, target, rcond=1e-10)[0]
        target = target - a @ coef
    along = float(np.linalg.norm(target))
    dof = max(n - int(others.size) - 1, 1)
    s2 = float(np.dot(residual, residual)) / dof
    tau = n / max(n_eff, 1.0)
    if along <= 1e-12 * max(float(np.linalg.norm(jac[:, j])), 1e-300):
        return math.inf
    return math.sqrt(tau * s2) / along


def size_over_sd(jac: np.ndarray, residual: np.ndarray, n_eff: float, keep: np.ndarray,
                 sizes: Sequence[int], shapes: Sequence[int], *, values: np.ndarray,
                 slope: np.ndarray, upper: np.ndarray) -> float:
    """The detection statistic of one effect: the largest ``|size| / sd`` over its sizes.

    Each size's standard deviation is :func:`conditional_sd` with the effect's ``shapes``
    held at their fitted values: a shape (a period, a time constant, a Stribeck velocity)
    means nothing when the size is zero (Davies 1977), so the test of the size does not let
    it roam; a drift still short of its asymptote determines its slope, not its level and
    time constant apart, and it is there all the same. The marginal standard deviation (the
    shape free, :func:`held_covariance`) answers how well the size is known, not whether it
    can be told from zero.

    Parameters
    ----------
    jac : ndarray, shape (n, p)
        Jacobian of the residual in the fit's coordinates (those ``keep`` was judged on).
    residual : ndarray, shape (n,)
    n_eff : float
    keep : ndarray of bool, shape (p,)
        :func:`kept_columns`.
    sizes, shapes : sequence of int
        Columns of the effect's sizes and of its shape parameters (those fitted).
    values : ndarray, shape (p,)
        Each column's parameter value (the sizes' in the reported units).
    slope : ndarray, shape (p,)
        d value / d coordinate of each column.
    upper : ndarray of bool, shape (p,)
        Columns on the upper bound of their range: a size pushed there is as large as the
        range lets it be (infinitely many sd from zero); one on its lower bound or moving
        nothing shows no size (0).

    Returns
    -------
    float
        0 for an effect with no size column.
    """
    keep_e = keep.copy()
    keep_e[list(shapes)] = False
    zs = [0.0]
    for j in sizes:
        if upper[j]:
            zs.append(math.inf)
        elif not keep_e[j]:
            zs.append(0.0)
        else:
            sd = conditional_sd(jac, residual, n_eff, j, keep_e) * abs(float(slope[j]))
            zs.append(abs(float(values[j])) / sd if sd > 0.0 else math.inf)
    return max(zs)


def profile_statistic(sse_with: float, sse_without: float, n_eff: float) -> float:
    """The profile (likelihood-ratio) form of the detection test: ``n_eff ln(SSE_without /
    SSE_with)``, each model fitted by its simulation error on the same run (the one without
    the effect refitted, not the other's values with the size zeroed).

    Under the hypothesis that the size is zero the statistic is about chi-square with one
    degree of freedom, so ``detection_sd ** 2`` is the level of the ``detection_sd`` test of
    :func:`size_over_sd` (its linearised, Wald, form). The two agree where the model is
    linear in the size; where it is far from linear (a friction level that moves every
    stick-slip stop) the linearised standard deviation can hold a size the data cannot do
    without within it, and the profile form decides (Bates & Watts, *Nonlinear Regression
    Analysis*, 1988, ch. 6; Seber & Wild, *Nonlinear Regression*, 1989, section 5.9). 0 when
    either error is not a positive finite number (no evidence either way).
    """
    ratio = sse_without / sse_with if sse_with > 0.0 else math.inf
    if not (math.isfinite(ratio) and ratio > 0.0 and math.isfinite(n_eff)):
        return 0.0
    return n_eff * math.log(ratio)


def least_detected(size_over_sd: Mapping[str, float], detection_sd: float
                   ) -> tuple[str, float] | None:
    """The effect whose statistic (:func:`size_over_sd`) lies within ``detection_sd``, the
    least significant first (the first of equals), with that statistic; None when every
    effect stands clear. The loops leave it out and fit again, until none is left."""
    worst: tuple[str, float] | None = None
    for name, z in size_over_sd.items():
        if z <= detection_sd and (worst is None or z < worst[1]):
            worst = (name, z)
    return worst
