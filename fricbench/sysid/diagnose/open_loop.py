"""Open-loop diagnosis: the position simulated free-run from the measured effort.

The axis is driven by its logged effort alone (:mod:`fricbench.axis.open_loop`), so the rigid
body is a double integrator and any unexplained force integrates into a drift of the position.
The fit therefore minimises the *simulation* (output) error of the position, each free-run
segment started from its own first ``n_init`` samples only, and the effect search judges a
candidate effect on the simulation error of **held-out** blocks of the run (fitted on the other
blocks, simulated free over the held-out block from its first samples). Nothing is detrended:
the reported errors are the raw free-run errors, drift included.

Model (plant row of :mod:`fricbench.axis.plant`, forces in the effort's unit)::

    M dv/dt = u - B v - F_eff(x, v)      always M, B; effects from the registry add F_eff terms

The effects are those of :mod:`fricbench.sysid.diagnose.effects` (their plant entries, as
many as each frees beside the others); a period is held (the position-dependent friction's at
twice the stroke, the cogging's where its starts from the run put it: :data:`DATA_STARTED`),
while the shapes of the effects in :data:`DATA_SHAPED` (a resonance, a Stribeck velocity) are
fitted with their sizes, from starts each effect finds in the run.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import OptimizeResult, least_squares
from scipy.signal import welch

from fricbench.axis import plant as PL
from fricbench.axis.open_loop import initial_state, simulate_open_loop
from fricbench.run_events import motion_sign
from fricbench.sysid.diagnose.criterion import (
    described_sd,
    effective_samples,
    held_covariance,
    kept_columns,
    least_detected,
    profile_statistic,
    size_over_sd,
)
from fricbench.sysid.diagnose.effects import describe_parameters, get_effect, size_entries
from fricbench.sysid.diagnose.effects.stribeck import _vs_range as vs_range
from fricbench.sysid.diagnose.leastsq import sumsq
from fricbench.sysid.diagnose.selection import Scored, select
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS, DiagnoseSettings, defaults
from fricbench.sysid.diagnose.signals import (
    disturbance_warning,
    noise_floor,
    open_loop_motion,
    sensor_lines,
)

__all__ = ["OpenLoopModel", "OpenLoopFit", "BASE_EFFECTS", "CANDIDATE_EFFECTS", "DATA_STARTED",
           "fit_open_loop", "search_open_loop", "diagnose_open_loop",
           "print_open_loop_summary", "simulate_model", "free_run_errors",
           "periodic_statistics", "free_run_floor"]

BASE_EFFECTS: tuple[str, ...] = ("coulomb_friction", "force_offset")
"""Effects of every open-loop model (with the mass and the viscous damping)."""

CANDIDATE_EFFECTS: tuple[str, ...] = ("asymmetric_friction", "stribeck_friction",
                                      "position_dependent_friction", "cogging", "compliance",
                                      "cogging_harmonic_2", "cogging_harmonic_3")
"""Effects the forward search tries, in this order (a cogging's harmonics once it is in)."""

DATA_SHAPED: tuple[str, ...] = ("compliance", "stribeck_friction")
"""Effects whose shape (a resonance and its damping, a Stribeck velocity) is fitted too, from
starts found in the data (:meth:`Effect.open_loop_starts`)."""

DATA_STARTED: tuple[str, ...] = (*DATA_SHAPED, "cogging")
"""Effects whose starts are found in the data: those of :data:`DATA_SHAPED`, and the cogging,
whose period the inverse dynamics' spectrum against position gives and the fit holds (a
period fitted by free-run error wanders between the minima its phase over the stroke makes:
0.0184 m from a start of 0.01426 m for a true 0.01424 m on a test run)."""

Log = Callable[[str], None]


@dataclass
class OpenLoopModel:
    """A rigid axis driven by its effort: a plant row and the effects switched on.

    Attributes
    ----------
    plant : ndarray, shape (N_PLANT,)
        Plant row (forces in the effort's unit, mass in effort unit per m/s^2).
    effects : tuple of str
        Registry effects in the model.
    """

    plant: np.ndarray = field(repr=False)
    effects: tuple[str, ...]

    def free(self) -> tuple[int, ...]:
        """Plant entries fitted: mass, damping and the sizes of the effects.

        An effect's entries are those it declares free beside the model's other effects
        (:meth:`Effect.free`, as in the closed loop: a direction-dependent Coulomb level is the
        force offset's twin while the axis moves, so with the offset in only the viscous
        asymmetry is fitted)."""
        idx = [PL.M, PL.B]
        for name in self.effects:
            eff = get_effect(name)
            # shapes found in the data (a resonance, a Stribeck velocity) are fitted; others
            # stay at their scales
            shaped = name in DATA_SHAPED
            idx += [i for i in eff.free(self.effects) if shaped or i not in eff.shape_parameters]
        return tuple(dict.fromkeys(idx))

    def describe(self, force_unit: str = "N") -> dict[str, object]:
        """Fitted parameters in SI units (forces in ``force_unit``)."""
        p = self.plant
        out: dict[str, object] = {"mass": float(p[PL.M]),
                                  f"viscous_{force_unit}_s_m": float(p[PL.B])}
        for name in self.effects:
            out[name] = describe_parameters(name, p, force_unit)
        return out


@dataclass
class OpenLoopFit:
    """The result of :func:`search_open_loop`.

    Attributes
    ----------
    model : OpenLoopModel
        Final model, fitted on the whole run.
    train_rms : float
        Free-run position error of ``model`` on the whole run (from its first samples), m.
    heldout : dict
        Held-out free-run error (rms, m) of every model the search judged, by effect set.
    steps : list of dict
        The search's decisions, in order (:class:`~fricbench.sysid.diagnose.selection.
        Selection`).
    idx : tuple of int
        The plant entries fitted in the final fit.
    sd : ndarray
        Their standard deviations (in ``idx`` order), from the Jacobian at the optimum.
    n_eff : float
        Independent samples the final fit's residual is worth.
    not_detected : list of dict
        Effects the search chose whose sizes lay within ``detection_sd`` standard deviations
        of zero in the final fit, so left out.
    profile_detected : dict
        Effects of the final model whose sizes lie within ``detection_sd`` standard deviations
        of zero by the Jacobian but that the profile form of the test detects
        (:func:`~fricbench.sysid.diagnose.criterion.profile_statistic`): their
        ``size_over_sd`` and ``profile_statistic``.
    floor : float
        Held-out free-run rms a perfect model of the chosen structure would still make
        (:func:`free_run_floor` of its block fits), m.
    """

    model: OpenLoopModel
    train_rms: float
    heldout: dict[str, float]
    steps: list[dict[str, object]]
    floor: float = 0.0
    idx: tuple[int, ...] = ()
    sd: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    n_eff: float = 0.0
    not_detected: list[dict[str, object]] = field(default_factory=list)
    profile_detected: dict[str, dict[str, float]] = field(default_factory=dict)

    def uncertainty(self, force_unit: str = "N") -> dict[str, object]:
        """Standard deviations of the reported parameters, keyed as :meth:`OpenLoopModel.
        describe` keys them."""
        return describe_uncertainty(self.model, self.idx, self.sd, force_unit)


def _scales(effort: np.ndarray, y: np.ndarray, ts: float) -> dict[str, float]:
    v = np.gradient(y, ts)
    force = max(float(np.sqrt(np.mean(effort ** 2))), 1e-12)
    speed = max(float(np.sqrt(np.mean(v ** 2))), 1e-12)
    stroke = max(float(np.ptp(y)), 1e-12)
    return {"force": force, "speed": speed, "stroke": stroke, "center": float(np.mean(y)),
            "v_max": max(float(np.max(np.abs(v))), 1e-12)}


def _switch_on(p: np.ndarray, name: str, sc: dict[str, float]) -> np.ndarray:
    """Fix an effect's shape parameters from the run's scales (sizes stay as they are)."""
    q = p.copy()
    if name == "position_dependent_friction":
        q[PL.PD_PERIOD] = 2.0 * sc["stroke"]
        q[PL.PD_CENTER] = sc["center"]
    elif name == "cogging" and not q[PL.COG_PERIOD] < sc["stroke"]:
        # inside its range until a start from the data gives the period (a force varying
        # smoothly along the stroke is the position-dependent friction's)
        q[PL.COG_PERIOD] = 0.5 * sc["stroke"]
    return q


def _param_scale(i: int, value: float, sc: dict[str, float]) -> float:
    if i == PL.COMP_RATIO:
        return 0.1
    if i == PL.COMP_FREQ:
        return max(0.1 * abs(value), 1e-3)
    if i == PL.COMP_ZETA:
        return 0.05
    if i == PL.VS:
        return 0.1 * sc["v_max"]
    if i == PL.M:
        return max(0.1 * abs(value), 1e-12)
    if i in (PL.B, PL.DB):
        return 0.1 * sc["force"] / sc["speed"]
    if i == PL.PD_GRAD:
        return 1.0 / sc["stroke"]
    if i in (PL.PD_SIN, PL.PD_COS):
        return 0.3
    return 0.05 * sc["force"]


def _bounds(i: int, ts: float, sc: dict[str, float]) -> tuple[float, float]:
    if i == PL.VS:
        return vs_range(sc["v_max"])
    if i == PL.COMP_RATIO:
        return 1e-3, 0.95
    if i == PL.COMP_FREQ:
        # what the samples can show: up to 0.45 x the sampling rate
        return 0.5, 0.45 / ts
    if i == PL.COMP_ZETA:
        return defaults().compliance_zeta_range
    if i == PL.M:
        return 1e-12, np.inf
    if i in (PL.B, PL.FC, PL.FS_EXCESS):
        # a viscous damping below zero feeds energy into the axis: the friction's decrease
        # with speed is the Stribeck friction's, not a negative damping's
        return 0.0, np.inf
    return -np.inf, np.inf


def _idim_start(effort: np.ndarray, y: np.ndarray, ts: float, effects: Sequence[str],
                sc: dict[str, float]) -> np.ndarray:
    """Plant row from the inverse dynamics (filtered differences) of the linear terms."""
    _, uf, v, acc = open_loop_motion(effort, y, ts)
    sgn = motion_sign(v, 0.02 * sc["v_max"])
    cols = [acc, v]
    idx = [PL.M, PL.B]
    if "coulomb_friction" in effects:
        cols.append(sgn)
        idx.append(PL.FC)
    if "force_offset" in effects:
        cols.append(np.ones_like(v))
        idx.append(PL.OFFSET)
    if "asymmetric_friction" in effects:
        # its free entries beside the others (the Coulomb asymmetry is the offset's twin)
        free = get_effect("asymmetric_friction").free(effects)
        if PL.DFC in free:
            cols.append(0.5 * np.abs(sgn))
            idx.append(PL.DFC)
        cols.append(0.5 * np.abs(v))
        idx.append(PL.DB)
    X = np.column_stack(cols)
    # u = M a + B v + fc sgn(v) + f0 [+ dfc/2 |sgn v| + dB/2 |v|]; a light ridge keeps dfc and f0
    # (the same force while moving) apart
    norm = np.sqrt(np.sum(X ** 2, axis=0)) + 1e-300
    Xn = X / norm
    lam = 1e-6 * X.shape[0]
    theta = np.linalg.solve(Xn.T @ Xn + lam * np.eye(len(idx)), Xn.T @ uf) / norm
    p = PL.default_row(max(float(theta[0]), 1e-6), 0.0, ts)
    for i, val in zip(idx[1:], theta[1:], strict=True):
        p[i] = val
    p[PL.FC] = max(p[PL.FC], 0.0)
    for name in effects:
        p = _switch_on(p, name, sc)
    return p


def simulate_model(plant: np.ndarray, effort: np.ndarray, y: np.ndarray, ts: float,
                   n_init: int, n_sub: int = 1) -> np.ndarray:
    """Free-run positions of plant rows from the effort, started from ``y[:n_init]`` only."""
    x0, v0 = initial_state(y, ts, n_init)
    out, _ = simulate_open_loop(plant, effort, ts, x0=x0, v0=v0, n_sub=n_sub)
    return out


def _segments_residual(rows: np.ndarray, effort: np.ndarray, y: np.ndarray, ts: float,
                       segments: Sequence[tuple[int, int]], n_init: int) -> np.ndarray:
    out = []
    for lo, hi in segments:
        ys = simulate_model(rows, effort[lo:hi], y[lo:hi], ts, n_init)
        out.append(ys[:, n_init:] - y[None, lo + n_init:hi])
    res = np.concatenate(out, axis=1)
    # a diverged row gets a large finite residual (the optimiser steps back)
    return np.nan_to_num(res, nan=10.0 * (float(np.ptp(y)) + 1.0))


@dataclass
class _Fit:
    """One output-error fit: the model, its rms error, and what its uncertainty needs."""

    model: OpenLoopModel
    rms: float
    idx: list[int]
    jac: np.ndarray = field(repr=False)
    residual: np.ndarray = field(repr=False)
    scale: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    on_bound: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool), repr=False)
    on_upper: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool), repr=False)


def _fit(model: OpenLoopModel, effort: np.ndarray, y: np.ndarray, ts: float, *,
         segments: Sequence[tuple[int, int]], n_init: int, max_nfev: int = 60) -> _Fit:
    sc = _scales(effort, y, ts)
    idx = list(model.free())
    p0 = model.plant.copy()
    scale = np.array([_param_scale(i, p0[i], sc) for i in idx])
    lo = np.array([_bounds(i, ts, sc)[0] for i in idx]) / scale
    hi = np.array([_bounds(i, ts, sc)[1] for i in idx]) / scale

    def rows(Z: np.ndarray) -> np.ndarray:
        P = np.repeat(p0[None, :], Z.shape[0], axis=0)
        P[:, idx] = Z * scale
        return P

    def fun(z: np.ndarray) -> np.ndarray:
        return _segments_residual(rows(z[None, :]), effort, y, ts, segments, n_init)[0]

    def jac(z: np.ndarray) -> np.ndarray:
        h = 1e-5
        Z = np.vstack([z, z + h * np.eye(z.size)])
        R = _segments_residual(rows(Z), effort, y, ts, segments, n_init)
        return ((R[1:] - R[0]) / h).T

    # the damping's bound (never below zero: a passive axis) is a constraint the fit must
    # meet, not a box to search in: trf scales its steps by the distance to every finite
    # bound, so the fit runs without it and is redone within it only when it ends below it
    # (from the projection of where it ended)
    def solve(z0: np.ndarray, lower: np.ndarray) -> OptimizeResult:
        return least_squares(fun, np.clip(z0, lower + 1e-9, hi - 1e-9), jac=jac,
                             bounds=(lower, hi), method="trf", x_scale=1.0, xtol=1e-10,
                             ftol=1e-10, gtol=1e-10, max_nfev=max_nfev)

    passive = np.array([i == PL.B for i in idx], dtype=bool)
    res = solve(p0[idx] / scale, np.where(passive, -np.inf, lo))
    if np.any(res.x[passive] < lo[passive]):
        res = solve(res.x, lo)
    p = p0.copy()
    p[idx] = res.x * scale
    # dr/dp = dr/dz / scale: the Jacobian in the plant row's own units
    edges = [_on_bound(i, p[i], ts, sc) for i in idx]
    return _Fit(OpenLoopModel(p, model.effects), float(np.sqrt(np.mean(res.fun ** 2))), idx,
                np.asarray(res.jac) / scale[None, :], np.asarray(res.fun), scale,
                np.array([e is not None for e in edges], dtype=bool),
                np.array([e is not None and e == _bounds(i, ts, sc)[1]
                          for i, e in zip(idx, edges, strict=True)], dtype=bool))


def fit_open_loop(model: OpenLoopModel, effort: np.ndarray, y: np.ndarray, ts: float, *,
                  segments: Sequence[tuple[int, int]], n_init: int,
                  max_nfev: int = 60) -> tuple[OpenLoopModel, float]:
    """Fit the model's free entries by free-run simulation error over ``segments``.

    Each segment ``[lo, hi)`` is simulated from the effort, its state taken from its first
    ``n_init`` samples; the error counts from sample ``lo + n_init``. Levenberg-Marquardt-like
    trust-region least squares with a forward-difference Jacobian whose rows run in one batch.

    Returns the fitted model and its rms simulation error over the segments, m.
    """
    fit = _fit(model, effort, y, ts, segments=segments, n_init=n_init, max_nfev=max_nfev)
    return fit.model, fit.rms


def _blocks(n: int, k: int) -> list[tuple[int, int]]:
    edges = np.linspace(0, n, k + 1).astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def _fit_multistart(effects: tuple[str, ...], effort: np.ndarray, y: np.ndarray, ts: float,
                    segments: Sequence[tuple[int, int]], n_init: int,
                    extra: Sequence[np.ndarray] = ()) -> _Fit:
    """Best fit (lowest error on ``segments``) from the inverse-dynamics start and ``extra``."""
    sc = _scales(effort, y, ts)
    sel = np.zeros(y.size, dtype=bool)
    for lo, hi in segments:
        sel[lo:hi] = True
    starts = [_idim_start(effort[sel], y[sel], ts, effects, sc), *extra]
    rows = []
    for p in starts:
        q = _switched_off(p, effects)
        for name in effects:
            q = _switch_on(q, name, sc)
        rows.append(q)
    for name in effects:
        if name in DATA_STARTED:
            rows = _data_starts(name, rows, effort, y, ts, segments, n_init, sel)
    best: _Fit | None = None
    for q in rows:
        fit = _fit(OpenLoopModel(q, effects), effort, y, ts, segments=segments, n_init=n_init)
        if best is None or fit.rms < best.rms:
            best = fit
    if best is None:
        raise ValueError("no start to fit the open-loop model from")
    return best


def _switched_off(p: np.ndarray, effects: Sequence[str]) -> np.ndarray:
    """The row with every size the model does not fit at zero: those of the library's effects
    not in ``effects`` (an effect left out, e.g. not detected, leaves no fixed force behind)
    and those an effect in the model does not free beside the others."""
    q = p.copy()
    for name in dict.fromkeys((*BASE_EFFECTS, *CANDIDATE_EFFECTS, *effects)):
        eff = get_effect(name)
        free = eff.free(effects) if name in effects else ()
        for i in eff.parameters:
            if i not in free and i not in eff.shape_parameters:
                q[i] = 0.0
    return q


def _data_starts(name: str, rows: list[np.ndarray], effort: np.ndarray, y: np.ndarray,
                 ts: float, segments: Sequence[tuple[int, int]], n_init: int,
                 sel: np.ndarray) -> list[np.ndarray]:
    """Rows where effect ``name`` is off get its starts from the data (the training samples
    ``sel``); of those, the best ``settings.n_data_starts`` by free-run error are kept, or all
    of them for an effect whose shape the fit holds (a cogging's period: a ripple at the
    right period without its harmonics can start further from the run than none at all)."""
    eff = get_effect(name)
    size = next(i for i in eff.parameters if i not in eff.shape_parameters)
    found = eff.open_loop_starts(effort[sel], y[sel], ts)
    keep = [q for q in rows if q[size] != 0.0]
    expanded = []
    for q in rows:
        if q[size] != 0.0:
            continue
        for start in found:
            r = q.copy()
            for i, v in start.items():
                r[i] = v
            expanded.append(r)
    if not expanded:
        return keep or rows
    if name not in DATA_SHAPED:
        return keep + expanded
    res = _segments_residual(np.stack(expanded), effort, y, ts, segments, n_init)
    order = np.argsort(np.sum(res ** 2, axis=1))[:defaults().n_data_starts]
    return keep + [expanded[int(i)] for i in order]


def _heldout(effects: tuple[str, ...], effort: np.ndarray, y: np.ndarray, ts: float,
             folds: Sequence[tuple[int, int]], n_init: int,
             fold_starts: dict[int, np.ndarray], settings: DiagnoseSettings) -> Scored:
    """The structure ``effects`` scored: its free-run error over the held-out blocks, each
    fitted on the other blocks and simulated free from its own first ``n_init`` samples."""
    parts = []
    fitted: dict[int, np.ndarray] = {}
    for j, (lo, hi) in enumerate(folds):
        train = [f for i, f in enumerate(folds) if i != j]
        extra = [fold_starts[j]] if j in fold_starts else []
        model = _fit_multistart(effects, effort, y, ts, train, n_init, extra).model
        fitted[j] = model.plant
        yh = simulate_model(model.plant, effort[lo:hi], y[lo:hi], ts, n_init)[0]
        parts.append(yh[n_init:] - y[lo + n_init:hi])
    e = np.concatenate(parts)
    sse = float(np.sum(e ** 2)) if np.all(np.isfinite(e)) else float("inf")
    k = len(OpenLoopModel(PL.default_row(1.0, 0.0, ts), effects).free())
    violation = _violation(effects, fitted, ts, _scales(effort, y, ts))
    return Scored(effects, sse, int(e.size), k, np.nan_to_num(e), violation, fitted)


def _violation(effects: tuple[str, ...], fitted: dict[int, np.ndarray], ts: float,
               sc: dict[str, float]) -> str | None:
    """The plausibility constraint a structure's block fits break: a fitted shape parameter
    (a resonance's frequency or damping) on a bound of its physical range in any block."""
    for name in effects:
        if name not in DATA_SHAPED:
            continue
        for i in get_effect(name).shape_parameters:
            for p in fitted.values():
                edge = _on_bound(i, p[i], ts, sc)
                if edge is not None:
                    return f"{name}: a shape parameter on its bound ({edge:.4g})"
    return None


def _on_bound(i: int, value: float, ts: float, sc: dict[str, float]) -> float | None:
    """The edge of entry ``i``'s range that ``value`` ended on (within
    ``settings.bound_tolerance`` of the span), or None; only
    a range with two finite edges (a physical range: a Stribeck velocity, a resonance) has
    edges to end on."""
    lo, hi = _bounds(i, ts, sc)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return None
    for edge in (lo, hi):
        if abs(value - edge) <= defaults().bound_tolerance * max(abs(edge), hi - lo):
            return edge
    return None


def _white_noise(e: np.ndarray, ts: float) -> float:
    """Standard deviation of the white part of a residual, from its spectrum's top fifth
    (0.4 .. 0.5 of the sampling rate), where a mass's response to any effort has died out
    (``1 / (M w^2)``) and only the sensor's noise is left: ``sigma^2 = P fs / 2``."""
    if e.size < 64:
        return float(np.std(e))
    f, pxx = welch(e - np.mean(e), fs=1.0 / ts, nperseg=min(e.size, 256))
    top = f >= 0.4 / ts
    return float(np.sqrt(np.median(pxx[top]) * 0.5 / ts))


def free_run_floor(fold_fits: dict[int, np.ndarray], effort: np.ndarray, y: np.ndarray,
                   ts: float, blocks: Sequence[tuple[int, int]], n_init: int,
                   draws: int = 4, seed: int = 0) -> float:
    """Held-out free-run rms a perfect model would still make, m: the noise of the position
    through the initial state taken from ``n_init`` noisy samples, plus the noise itself.

    Each block's fitted model (``fold_fits``) runs free from its block's own start; the
    position noise (from the top of its residual's spectrum, :func:`_white_noise`) is added
    ``draws`` times, the state re-estimated from the noisy samples and the model run again.
    """
    rng = np.random.default_rng(seed)
    sq, count = 0.0, 0
    for j, (lo, hi) in enumerate(blocks):
        if j not in fold_fits:
            continue
        plant = fold_fits[j]
        y_model = simulate_model(plant, effort[lo:hi], y[lo:hi], ts, n_init)[0]
        e = y_model - y[lo:hi]
        if not np.all(np.isfinite(e)):
            continue
        sigma = _white_noise(e, ts)
        for _ in range(draws):
            noisy = y_model + sigma * rng.standard_normal(hi - lo)
            again = simulate_model(plant, effort[lo:hi], noisy, ts, n_init)[0]
            d = (again - noisy)[n_init:]
            if np.all(np.isfinite(d)):
                sq += float(np.sum(d ** 2))
                count += d.size
    return float(np.sqrt(sq / count)) if count else 0.0


def _uncertainty(fit: _Fit, settings: DiagnoseSettings) -> tuple[np.ndarray, float]:
    """Standard deviations of the fit's free entries (in ``fit.idx`` order) and ``n_eff``.

    The marginal ones, reported beside the parameters: an entry on a bound of its range at the
    optimum (a Stribeck velocity at its smallest) or one the residual does not move (judged in
    the fit's scaled units) is held at its value, with the closed loop's rule
    (:func:`~fricbench.sysid.diagnose.criterion.kept_columns`): its standard deviation is that
    of :data:`~fricbench.sysid.diagnose.criterion.UNIDENTIFIED`, and the others' covariance is
    taken without it (:func:`~fricbench.sysid.diagnose.criterion.held_covariance`)."""
    n_eff = effective_samples(fit.residual, settings.max_lag_share)
    scale = fit.scale if fit.scale.size == fit.jac.shape[1] else np.ones(fit.jac.shape[1])
    held = fit.on_bound if fit.on_bound.size == scale.size else np.zeros(scale.size, dtype=bool)
    keep = kept_columns(fit.jac * scale[None, :], held)
    cov = held_covariance(fit.jac, fit.residual, n_eff, keep)
    return np.sqrt(np.maximum(np.diag(cov), 0.0)), n_eff


def _size_over_sd(fit: _Fit, n_eff: float) -> dict[str, float]:
    """Per effect with a size, the detection statistic of the closed loop's one rule
    (:func:`~fricbench.sysid.diagnose.criterion.size_over_sd`): the largest ``|size| / sd``,
    ``sd`` taken with the effect's fitted shape (a Stribeck velocity, a resonance) held at its
    value and projected off the other kept columns, not the marginal ``sd`` of
    :func:`_uncertainty` that is reported (how well a value is known, the shape free)."""
    p = len(fit.idx)
    scale = fit.scale if fit.scale.size == p else np.ones(p)
    held = fit.on_bound if fit.on_bound.size == p else np.zeros(p, dtype=bool)
    upper = fit.on_upper if fit.on_upper.size == p else np.zeros(p, dtype=bool)
    # the fit's own coordinates (z = value / scale): those the columns are kept in
    jac = fit.jac * scale[None, :]
    keep = kept_columns(jac, held)
    values = fit.model.plant[list(fit.idx)]
    col = {i: j for j, i in enumerate(fit.idx)}
    out: dict[str, float] = {}
    for name in fit.model.effects:
        sizes = size_entries(name, fit.idx)
        if not sizes:
            continue
        shapes = [col[i] for i in get_effect(name).shape_parameters if i in col]
        out[name] = size_over_sd(jac, fit.residual, n_eff, keep, [col[i] for i in sizes],
                                 shapes, values=values, slope=scale, upper=upper)
    return out


def _least_detected(fit: _Fit, n_eff: float, settings: DiagnoseSettings,
                    skip: Sequence[str] = ()) -> tuple[str, float] | None:
    """The effect whose sizes all lie within ``detection_sd`` standard deviations of zero
    (:func:`_size_over_sd`), the least significant first, with its statistic; None when every
    one is detected (:func:`~fricbench.sysid.diagnose.criterion.least_detected`). Effects in
    ``skip`` (detected otherwise) are not considered."""
    return least_detected({e: z for e, z in _size_over_sd(fit, n_eff).items() if e not in skip},
                          settings.detection_sd)


def describe_uncertainty(fit_model: OpenLoopModel, idx: Sequence[int], sd: np.ndarray,
                         force_unit: str = "N") -> dict[str, object]:
    """Standard deviations of :meth:`OpenLoopModel.describe`'s values (the delta method)."""
    cov = np.diag(np.asarray(sd, dtype=float) ** 2)
    idx = list(idx)
    row = fit_model.plant
    steps = np.array([1e-6 * max(abs(row[i]), 1e-9) for i in idx])
    out: dict[str, object] = {}
    lin = described_sd(lambda q: {"mass": float(q[PL.M]),
                                  f"viscous_{force_unit}_s_m": float(q[PL.B])},
                       row, idx, cov, steps)
    out.update(lin)
    for name in fit_model.effects:
        out[name] = described_sd(functools.partial(describe_parameters, name,
                                                   force_unit=force_unit),
                                 row, idx, cov, steps)
    return out


def search_open_loop(effort: np.ndarray, y: np.ndarray, ts: float, *, n_init: int = 20,
                     folds: int | None = None, candidates: Sequence[str] = CANDIDATE_EFFECTS,
                     max_effects: int | None = None,
                     settings: DiagnoseSettings = DEFAULT_SETTINGS, force_unit: str = "N",
                     log: Log | None = None) -> OpenLoopFit:
    """The diagnosis' one search on an open-loop run, then the final fit and its uncertainty.

    The run is cut into ``folds`` contiguous blocks. A structure (the effects in the model) is
    scored by its held-out free-run error, every block fitted on the others
    (:func:`_heldout`), and judged by the one criterion
    (:func:`~fricbench.sysid.diagnose.criterion.criterion_change`) in the one search
    (:func:`~fricbench.sysid.diagnose.selection.select`: forward, then one backward pass).
    The chosen structure is then fitted on the whole run by its simulation error (all its
    parameters together, from the blocks' fits), the standard deviations of its parameters
    taken from the Jacobian at that optimum; an effect whose every size lies within
    :attr:`~DiagnoseSettings.detection_sd` of zero is not detected (the closed loop's test,
    :func:`_size_over_sd`: its fitted shape held): it leaves the model, which is fitted again
    without it.

    Parameters
    ----------
    effort, y : ndarray, shape (K,)
        Measured effort and position (m).
    ts : float
        Sample time, s.
    n_init : int
        Samples of each segment used for its initial state.
    folds : int, optional
        Held-out blocks (default: ``settings.folds``).
    candidates : sequence of str
        Registry effects to try beyond :data:`BASE_EFFECTS`.
    max_effects : int, optional
        Most effects added to the base model (default: ``settings.max_effects``).
    settings : DiagnoseSettings
    force_unit : str
        The effort's unit, for the figures of an effect not detected.
    log : callable, optional
        Progress lines.
    """
    if folds is not None or max_effects is not None:
        settings = dataclasses.replace(
            settings, folds=settings.folds if folds is None else folds,
            max_effects=settings.max_effects if max_effects is None else max_effects)
    effort = np.asarray(effort, dtype=float)
    y = np.asarray(y, dtype=float)
    if effort.shape != y.shape or effort.ndim != 1:
        raise ValueError(f"effort, y: expected two 1-D arrays of one length, got shapes "
                         f"{effort.shape} and {y.shape}")
    if y.size // settings.folds < 5 * n_init:
        raise ValueError(f"folds={settings.folds!r}: blocks of {y.size // settings.folds} "
                         f"samples are too short for n_init={n_init!r}")
    say = log or (lambda _s: None)
    blocks = _blocks(y.size, settings.folds)

    def score(structure: tuple[str, ...], current: Scored) -> Scored:
        starts = current.state if set(current.structure) <= set(structure) else {}
        return _heldout(structure, effort, y, ts, blocks, n_init, starts, settings)

    base = _heldout(BASE_EFFECTS, effort, y, ts, blocks, n_init, {}, settings)
    say(f"open loop: base {', '.join(BASE_EFFECTS)}: held-out rms {1e3 * base.rms:.4g} mm")
    chosen = select(base, [get_effect(c) for c in candidates if c not in BASE_EFFECTS],
                    score, settings, say, describe=lambda v: f"{1e3 * v:.4g} mm")
    effects = chosen.best.structure
    starts = list(chosen.best.state.values())
    floor = free_run_floor(chosen.best.state, effort, y, ts, blocks, n_init)
    full = [(0, y.size)]
    fit = _fit_multistart(effects, effort, y, ts, full, n_init, starts)
    sd, n_eff = _uncertainty(fit, settings)
    not_detected: list[dict[str, object]] = []
    # effects within their sd that the profile form of the test detects (in the current fit)
    profiled: dict[str, dict[str, float]] = {}
    for _ in range(2 * len(effects)):
        weak = _least_detected(fit, n_eff, settings, skip=tuple(profiled))
        if weak is None:
            break
        name, z = weak
        without = tuple(e for e in effects if e != name)
        refit = _fit_multistart(without, effort, y, ts, full, n_init, [fit.model.plant])
        stat = profile_statistic(sumsq(fit.residual), sumsq(refit.residual), n_eff)
        if stat > settings.detection_sd ** 2:
            # the linearised sd holds it within, the data cannot do without it: detected
            profiled[name] = {"size_over_sd": z, "profile_statistic": stat}
            say(f"  {name}: within {settings.detection_sd:g} standard deviations of zero "
                f"(|size|/sd {z:.3g}), but the fit without it raises n_eff ln(SSE) by "
                f"{stat:.3g} > {settings.detection_sd ** 2:g}: detected")
            continue
        not_detected.append({"effect": name, "size_over_sd": z,
                             "parameters": describe_parameters(name, fit.model.plant,
                                                               force_unit),
                             "sd": describe_uncertainty(fit.model, fit.idx, sd,
                                                        force_unit).get(name, {})})
        say(f"  {name}: within {settings.detection_sd:g} standard deviations of zero "
            f"(|size|/sd {z:.3g}): not detected, fitted again without it")
        effects, fit, profiled = without, refit, {}
        sd, n_eff = _uncertainty(fit, settings)
    say(f"open loop: final {', '.join(effects) or 'rigid body'}: train free-run rms "
        f"{1e3 * fit.rms:.4g} mm")
    return OpenLoopFit(fit.model, fit.rms, chosen.scores, chosen.decisions, floor=floor,
                       idx=tuple(fit.idx), sd=sd, n_eff=n_eff, not_detected=not_detected,
                       profile_detected=profiled)


def free_run_errors(y_sim: np.ndarray, y: np.ndarray, n_init: int) -> dict[str, float]:
    """Raw free-run error statistics from sample ``n_init`` on (nothing detrended), m."""
    e = y_sim[n_init:] - y[n_init:]
    ym = y[n_init:]
    sse = float(np.sum(e ** 2))
    sst = float(np.sum((ym - ym.mean()) ** 2))
    return {"rms": float(np.sqrt(np.mean(e ** 2))), "max": float(np.max(np.abs(e))),
            "final": float(e[-1]), "r2": 1.0 - sse / sst if sst > 0.0 else float("nan")}


def periodic_statistics(y_sim: np.ndarray, y: np.ndarray, effort: np.ndarray,
                        ts: float, n_init: int) -> dict[str, float] | None:
    """Per-period errors and the noise from the spread between periods, for periodic runs.

    The period is the effort's autocorrelation peak; a run is periodic when that peak's
    normalised value exceeds 0.9 and at least two whole periods fit. The noise is the rms
    deviation of each period's measured position, after removing that period's mean (a drift
    between periods is motion, not noise), from the mean period shape. Returns None otherwise.
    """
    u = effort - effort.mean()
    n = u.size
    spec = np.fft.rfft(u, 2 * n)
    ac = np.fft.irfft(spec * np.conj(spec))[:n]
    if ac[0] <= 0.0:
        return None
    ac = ac / ac[0]
    lo = max(int(0.05 * n / 10), 10)
    if n // 2 <= lo:
        return None
    # the first lag past the zero lag's hump with the highest correlation
    neg = np.nonzero(ac[:n // 2] < 0.0)[0]
    if neg.size == 0:
        return None
    start = int(neg[0])
    lag = start + int(np.argmax(ac[start:n // 2]))
    peak = float(ac[lag]) * n / (n - lag)
    n_per = n // lag
    if peak < 0.9 or n_per < 2:
        return None
    e = (y_sim - y)[:n_per * lag].reshape(n_per, lag)
    shapes = y[:n_per * lag].reshape(n_per, lag)
    shapes = shapes - shapes.mean(axis=1, keepdims=True)
    noise = float(np.sqrt(np.mean((shapes - shapes.mean(axis=0)) ** 2) * n_per / (n_per - 1)))
    per_rms = np.sqrt(np.mean(e ** 2, axis=1))
    return {"period_s": lag * ts, "periods": float(n_per),
            "rms_per_period_mean": float(per_rms.mean()),
            "rms_per_period_min": float(per_rms.min()),
            "rms_per_period_max": float(per_rms.max()),
            "noise_between_periods": noise}


def _effort_relerr(plant: np.ndarray, effort: np.ndarray, y: np.ndarray, ts: float) -> float:
    """Relative rms error (%) of the inverse dynamics ``u = M a + F(x, v)`` on filtered data."""
    yf, uf, v, acc = open_loop_motion(effort, y, ts)
    # u = M a + (B + fv) v + F_f(x, v) + f0 + F_cog(x)
    u_hat = plant[PL.M] * acc + PL.sliding_force(plant, yf, v)
    return float(100.0 * np.linalg.norm(uf - u_hat) / max(float(np.linalg.norm(uf)), 1e-300))


def _evaluate(fit_model: OpenLoopModel, linear: OpenLoopModel, effort: np.ndarray,
              y: np.ndarray, ts: float, n_init: int) -> dict[str, object]:
    y_lin = simulate_model(linear.plant, effort, y[:n_init], ts, n_init)[0]
    y_fin = simulate_model(fit_model.plant, effort, y[:n_init], ts, n_init)[0]
    before = free_run_errors(y_lin, y, n_init)
    after = free_run_errors(y_fin, y, n_init)
    out: dict[str, object] = {
        "position": {"rms_before": before["rms"], "rms_after": after["rms"],
                     "max_before": before["max"], "max_after": after["max"],
                     "final_error_after": after["final"], "r2_after": after["r2"]},
        "effort": {"relerr_before_pct": _effort_relerr(linear.plant, effort, y, ts),
                   "relerr_after_pct": _effort_relerr(fit_model.plant, effort, y, ts)},
    }
    per = periodic_statistics(y_fin, y, effort, ts, n_init)
    if per is not None:
        out["periodic"] = per
    return out


def diagnose_open_loop(t: np.ndarray, effort: np.ndarray, y: np.ndarray, *,
                       validate: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
                       n_init: int = 20, force_unit: str = "N", folds: int | None = None,
                       max_effects: int | None = None,
                       settings: DiagnoseSettings = DEFAULT_SETTINGS,
                       log: Log | None = None, position_unit: tuple[str, float] = ("m", 1.0)
                       ) -> dict[str, object]:
    """Open-loop diagnosis of a run: the JSON-ready report of ``fricbench diagnose --open-loop``.

    ``position`` is the free-run simulation error of the measured position from the effort
    (``before``: the linear rigid body, mass and viscous damping, fitted the same way;
    ``after``: the model the held-out search selected), raw, drift included; ``effort`` the
    relative error of the inverse dynamics; ``validation`` the same on ``validate``
    (``(t, effort, y)`` of another run, simulated from its first ``n_init`` samples only).

    Lines of the mains in the final free-run residual (an open-loop run has no reference, so
    no rests: :func:`~fricbench.sysid.diagnose.signals.sensor_lines`) are a sensor
    disturbance: listed in ``sensor_disturbance`` (amplitudes also in ``position_unit``, the
    log's unit and its size in SI), with a warning, their power added to ``noise_floor``.
    """
    ts = float(np.median(np.diff(t)))
    warnings: list[str] = []
    fit = search_open_loop(effort, y, ts, n_init=n_init, folds=folds,
                           max_effects=max_effects, settings=settings, force_unit=force_unit,
                           log=log)
    folds = settings.folds if folds is None else folds
    for item in fit.not_detected:
        warnings.append(f"{item['effect']} not detected: the search chose it, but in the final "
                        f"fit its size lies within {settings.detection_sd:g} standard "
                        f"deviations of zero (|size|/sd {float(item['size_over_sd']):.3g}); "  # type: ignore[arg-type]
                        "left out")
    for name, detected in fit.profile_detected.items():
        warnings.append(f"{name}: its size lies within {settings.detection_sd:g} standard "
                        f"deviations of zero by the Jacobian (|size|/sd "
                        f"{detected['size_over_sd']:.3g}), but the fit without it raises "
                        f"n_eff ln(SSE) by {detected['profile_statistic']:.3g} > "
                        f"{settings.detection_sd ** 2:g} (the same test without the "
                        "linearisation): detected, its reported standard deviation the "
                        "linearised one")
    sc = _scales(effort, y, ts)
    p_lin = _idim_start(effort, y, ts, (), sc)
    p_lin[[PL.FC, PL.OFFSET]] = 0.0
    lin = OpenLoopModel(p_lin, ())
    lin, _ = fit_open_loop(lin, effort, y, ts, segments=[(0, y.size)], n_init=n_init)
    train = _evaluate(fit.model, lin, effort, y, ts, n_init)
    pos = train["position"]
    assert isinstance(pos, dict)
    per = train.get("periodic")
    rms = float(pos["rms_after"])
    # the sensor's noise (third differences of the position, the motion's being small), and
    # the mains' lines of the final free run's residual: no motion, so floor
    noise = noise_floor(y, np.zeros_like(y))
    resid = y - simulate_model(fit.model.plant, effort, y[:n_init], ts, n_init)[0]
    lines = (sensor_lines(resid, ts, [(0, y.size)], "residual", settings,
                          floor=noise.sensor_rms) if np.all(np.isfinite(resid)) else [])
    floor = fit.floor
    if lines:
        noise = noise.with_lines(lines)
        floor = math.hypot(fit.floor, noise.disturbance_rms)
        warnings.append(disturbance_warning(lines, *position_unit))
    # the three verdicts of the closed-loop diagnosis (fricbench.sysid.diagnose.verdict), by
    # its rule: effects against the linear rigid body, judged on the held-out (validation,
    # else the training run's free-run) position; at the floor when the free run is within
    # settings.floor_factor floors of a held-out free run (the noise between periods, when the
    # excitation repeats, is reported beside it: it was the floor, at its own factor, a tuned
    # periodic_floor_factor, until the open loop had a floor of its own)
    at_floor = floor > 0.0 and rms <= settings.floor_factor * floor
    periods = ""
    if isinstance(per, dict) and per["noise_between_periods"] > 0.0:
        periods = (f"; {rms / per['noise_between_periods']:.3g}x the noise between its "
                   "periods")
    if at_floor:
        residual = (f"at the noise floor (within {settings.floor_factor:g}x the floor of a "
                    f"held-out free run{periods})")
    elif floor > 0.0:
        residual = (f"free-run error {rms / floor:.3g}x the floor of a held-out free run"
                    f"{periods}: the drift of the rigid-body mode integrates what the model "
                    "misses")
    else:
        residual = "no floor to compare with: the free-run error is reported raw"
    held = train["position"]
    name = "training (free run)"
    if validate is not None:
        held = _evaluate(fit.model, lin, validate[1], validate[2], ts, n_init)["position"]
        name = "validation"
    assert isinstance(held, dict)
    fell = float(held["rms_after"]) < (1.0 - settings.heldout_gain) * float(held["rms_before"])
    effects = list(fit.model.effects)
    if effects and fell:
        verdict, reason = "explained", (f"{', '.join(effects)} added to the linear rigid body; "
                                        f"the {name} run's free-run position error fell")
    elif effects:
        verdict, reason = "not_explained", (f"{', '.join(effects)} added, but the {name} run's "
                                            "free-run position error did not fall by more "
                                            f"than {100 * settings.heldout_gain:.0f} %")
    elif at_floor:
        verdict, reason = "nothing_to_explain", "the linear rigid body is at the noise floor"
    else:
        verdict, reason = "not_explained", "no candidate effect explains the residual"
    if float(pos["rms_after"]) > float(pos["rms_before"]):
        warnings.append("the selected model simulates worse than the linear rigid body on the "
                        "whole run (it was judged on held-out blocks)")
    report: dict[str, object] = {
        "mode": "open_loop",
        "verdict": verdict,
        "verdict_detail": {"verdict": verdict, "reason": reason, "residual": residual},
        "effects": list(fit.model.effects),
        "parameters": fit.model.describe(force_unit),
        "parameter_sd": fit.uncertainty(force_unit),
        # the sensor's noise and the floor of a held-out free run from a noisy start (with
        # the sensor's lines' power added)
        "noise_floor": dict(noise.to_dict(), prediction_floor_m=floor),
        "sensor_disturbance": [ln.to_dict(position_unit[1], position_unit[0]) for ln in lines],
        "not_detected": fit.not_detected,
        "profile_detected": fit.profile_detected,
        "position": train["position"],
        "effort": train["effort"],
        "search": {"heldout_rms_m": fit.heldout, "steps": fit.steps, "folds": folds,
                   "n_init": n_init, "criterion": "n_eff ln(SSE_heldout / n) + "
                   f"{DEFAULT_SETTINGS.penalty:g} k", "n_eff_final_fit": fit.n_eff},
        "linear_model": {"parameters": lin.describe(force_unit)},
        "warnings": warnings,
    }
    if per is not None:
        report["periodic"] = per
    if validate is not None:
        tv, uv, yv = validate
        report["validation"] = _evaluate(fit.model, lin, uv, yv, ts, n_init)
    return report


def print_open_loop_summary(report: dict[str, object], elapsed: float) -> None:
    """Human summary of an open-loop report (stdout)."""
    v = report["verdict_detail"]
    assert isinstance(v, dict)
    print(f"verdict: {v['verdict']}: {v['reason']}")
    effects = report["effects"]
    assert isinstance(effects, list)
    print(f"effects (open loop, judged on held-out blocks): {', '.join(effects)}")
    print(f"parameters: {report['parameters']}")
    for name in ("position", "validation"):
        block = report.get(name)
        if not isinstance(block, dict):
            continue
        pos = block["position"] if name == "validation" else block
        eff = (block.get("effort") if name == "validation" else report["effort"])
        assert isinstance(pos, dict) and isinstance(eff, dict)
        print(f"{name}: free-run position rms {1e3 * pos['rms_before']:.4g} -> "
              f"{1e3 * pos['rms_after']:.4g} mm, max {1e3 * pos['max_before']:.4g} -> "
              f"{1e3 * pos['max_after']:.4g} mm; effort relerr "
              f"{eff['relerr_before_pct']:.3f} -> {eff['relerr_after_pct']:.3f} %")
    per = report.get("periodic")
    if isinstance(per, dict):
        print(f"periodic: {per['periods']:.0f} periods of {per['period_s']:.4g} s, rms per "
              f"period {1e3 * per['rms_per_period_min']:.4g}..{1e3 * per['rms_per_period_max']:.4g}"
              f" mm, noise between periods {1e6 * per['noise_between_periods']:.3g} um")
    warnings = report.get("warnings")
    for w in warnings if isinstance(warnings, list) else []:
        print(f"warning: {w}", file=sys.stderr)
    print(f"elapsed: {elapsed:.1f} s")
