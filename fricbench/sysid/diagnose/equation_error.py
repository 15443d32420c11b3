"""A loop and its friction identified together by equation error (linear least squares).

A position-only run hides the drive's command, but a linear law is linear in its gains: per
unit mass, ``a + B v + F(v) = u``, with the command of a PID position loop (the cascade of
:class:`~fricbench.sysid.diagnose.controllers.CascadeController` with a position integral)
``u = wv kp e + wv kvff F v_r - wv F v_x + wv kpi S_e + kaff a_r + c``, where ``e = x_r - x``,
``F`` is the derivative filter, ``v_x`` the backward difference of the measured position,
``S_e`` the running integral of ``e`` and ``c`` the integral's value at the start. Given the
filter's time constant (and a Stribeck velocity), the gains, the damping and the friction levels
are the coefficients of one least-squares problem on the measured motion: no start, no local
minimum. The output-error fits (:class:`~fricbench.sysid.diagnose.models.PositionFit`) start
from it. Their own starts are a grid of standard loops, and with stiction in the loop the
joint fit of a loop and its friction has many minima: on the second simulator's stribeck/10
(a PID with a filtered derivative and a one-sample delay, breakaway 1.8 times the Coulomb
level) the best refined grid start left 84 um where the true loop with its friction leaves
0.8 um.

The equation error is biased where the measured acceleration is noisy (it is taken from the
filtered position, and every column is filtered alike), and it ignores the samples at rest,
where friction holds the axis with whatever force it takes: its result is a start, refined by
output error, never reported as such.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import signal

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.controllers import CascadeController
from fricbench.sysid.diagnose.criterion import effective_samples, parameter_covariance
from fricbench.sysid.diagnose.leastsq import solve_ls, sumsq
from fricbench.sysid.diagnose.models import GreyBox
from fricbench.sysid.diagnose.parameters import Bounds
from fricbench.sysid.diagnose.prepared import Prepared
from fricbench.sysid.diagnose.settings import defaults
from fricbench.sysid.diagnose.signals import decimate_columns

__all__ = ["EquationErrorFit", "loop_by_equation_error", "delay_steps"]


def delay_steps(ts: float) -> tuple[int, ...]:
    """The delays of ``settings.delay_steps`` a loop of period ``ts`` (s) may have: at most the
    grid's longest counted in periods of the drive's own loop (``settings.loop_ts``)."""
    cfg = defaults()
    longest = max(cfg.delay_steps) * cfg.loop_ts
    return tuple(d for d in cfg.delay_steps if d * ts <= longest * (1.0 + 1e-9))

_FRICTION = ("coulomb_friction", "stribeck_friction")


@dataclass
class EquationErrorFit:
    """One loop with friction identified by equation error.

    Attributes
    ----------
    model : GreyBox
        The loop (a PID of :class:`CascadeController`) and a plant row per unit mass with the
        damping and friction found (the delay is not part of the model: it only aligns the
        regression).
    relerr : float
        Relative rms equation error on the sliding rows.
    delay : int
        Command delay of the regression, log samples.
    filter_steps : float
        Derivative filter's time constant, log samples.
    """

    model: GreyBox
    relerr: float
    delay: int
    filter_steps: float


def _first_order(x: np.ndarray, pole: float) -> np.ndarray:
    if pole <= 0.0:
        return x.copy()
    return signal.lfilter([1.0 - pole], [1.0, -pole], x)


def _shifted(col: np.ndarray, d: int) -> np.ndarray:
    """``col`` delayed by ``d`` samples and averaged over two (the command is held over a
    period, the acceleration is a central difference): ``(c[k-d] + c[k-d-1]) / 2``."""
    out = np.empty_like(col)
    lag = np.concatenate([np.repeat(col[:1], d + 1, axis=0), col])
    out[:] = 0.5 * (lag[1:col.shape[0] + 1] + lag[:col.shape[0]])
    return out


def _running_integral(col: np.ndarray, ts: float) -> np.ndarray:
    """``ts`` times the sum of ``col`` before each sample (the integral a law holds then)."""
    return ts * np.concatenate([[0.0], np.cumsum(col)[:-1]])


def _command(ctrl: CascadeController, cols: dict[str, np.ndarray], steps: float,
             ts: float) -> np.ndarray:
    """The law's command per unit mass on the measured motion (its filter at ``steps``):
    ``wv (e_v + I) + kaff a_r`` with ``e_v = kp e + F (kvff v_r - v_x)`` and
    ``I = int(ki e_v + kpi e)``."""
    pole = steps / (steps + 1.0)
    e_v = ctrl.kp * cols["e"] + _first_order(ctrl.kvff * cols["vr"] - cols["dx"], pole)
    integral = _running_integral(ctrl.ki * e_v + ctrl.kpi * cols["e"], ts)
    return ctrl.wv * (e_v + integral) + ctrl.kaff * cols["ar"]


def _feedforward_detected(X: np.ndarray, lhs: np.ndarray, coef: np.ndarray) -> bool:
    """Whether the regression tells the velocity feedforward from 1: ``wv (kvff - 1)``, the
    difference of the coefficients of columns 1 and 2, lies more than
    ``settings.detection_sd`` standard deviations from zero.

    The standard deviation is the least-squares one inflated by the residual's correlation
    (:func:`~fricbench.sysid.diagnose.criterion.parameter_covariance`, the regressors being
    the residual's Jacobian; a direction the data do not determine is not detected), as the
    effects' sizes are judged (Ljung 1999, section 9.6). Only then is the velocity integral's
    rate, which the regression holds as ``wv ki (kvff - 1)``, read from it."""
    cfg = defaults()
    r = lhs - X @ coef
    cov = parameter_covariance(X, r, effective_samples(r, cfg.max_lag_share))
    g = np.zeros(X.shape[1])
    g[1], g[2] = 1.0, -1.0
    var = float(g @ cov @ g)
    diff = float(coef[1] - coef[2])
    return bool(np.isfinite(var) and abs(diff) > cfg.detection_sd * math.sqrt(max(var, 0.0)))


def _law(coef: np.ndarray, pole: float, cascade: bool) -> CascadeController:
    """The law of one regression's coefficients (``wv kp'``, ``wv kvff``, ``wv``,
    ``wv (ki kp + kpi)``, ``kaff``, the integral's start, ``wv ki (kvff - 1)``; ``kp' = kp +
    ki``, the velocity integral acting like a position gain on the error). A cascade with
    the velocity PI's integral when ``cascade`` (the feedforward told from 1,
    :func:`_feedforward_detected`) and the gains come out positive, else a PID."""
    wv = float(coef[2])
    kp_all, kvff, k_se = float(coef[0]) / wv, float(coef[1]) / wv, float(coef[3]) / wv
    if cascade and kvff != 1.0:
        ki = float(coef[6]) / (wv * (kvff - 1.0))
        kp = kp_all - ki
        if ki > 0.0 and kp > 0.0:
            return CascadeController(wv=wv, kp=kp, ki=ki, kvff=kvff, kaff=float(coef[4]),
                                     kpi=max(k_se - ki * kp, 0.0), vel_pole=pole)
    return CascadeController(wv=wv, kp=kp_all, kvff=kvff, kaff=float(coef[4]),
                             kpi=max(k_se, 1e-9 * wv * wv), vel_pole=pole)


def _plant_by_equation_error(prep: Prepared, b: Bounds, u: np.ndarray, delay: int,
                             effects: tuple[str, ...],
                             lowpass: Callable[[np.ndarray], np.ndarray],
                             mask: np.ndarray) -> np.ndarray | None:
    """The damping and friction under a given command: ``a + B v + F(v) = u`` at the full
    rate, on the samples sliding faster than 2 % of the top speed (the decimated rows of the
    joint fit lose most of the slow sliding, where the Stribeck friction acts), with the
    Stribeck velocity searched on a grid. Returns the plant row (None: nothing sliding)."""
    vf, af = prep.vf, prep.af
    rows = (np.abs(vf) > 0.02 * float(np.max(np.abs(vf)))) & mask
    if np.count_nonzero(rows) < 20:
        return None
    lhs = (lowpass(_shifted(u, delay)) - af)[rows]
    sgn = np.sign(vf)
    grid = (np.geomspace(max(2e-3 * b.v_max, 1e-7), max(0.3 * b.v_max, 2e-7), 15)
            if len(effects) == 2 else np.array([math.nan]))
    best: tuple[float, float, np.ndarray] | None = None
    for vs in grid:
        c = [vf, sgn]
        if len(effects) == 2:
            c.append(sgn * np.exp(-(vf / vs) ** 2))
        # a constant: the integral's start, which the loop's regression held
        X = np.column_stack([*c, np.ones_like(vf)])[rows]
        coef = solve_ls(X, lhs, np.array([True] * len(c) + [False]))
        r = sumsq(lhs - X @ coef)
        if np.all(np.isfinite(coef)) and (best is None or r < best[0]):
            best = (r, float(vs), coef)
    if best is None:
        return None
    _, vs, coef = best
    row = CL.default_plant(1.0, float(coef[0]))
    row[CL.I_FC] = float(coef[1])
    if len(effects) == 2:
        row[CL.I_FS] = float(coef[2])
        row[CL.I_VS] = vs
    return row


def loop_by_equation_error(prep: Prepared, b: Bounds, effects: Sequence[str] = _FRICTION[:1],
                           *, n_best: int = 2, mask: np.ndarray | None = None,
                           delays: Sequence[int] | None = None) -> list[EquationErrorFit]:
    """The best loops with friction by equation error over the filter and delay grids.

    Two stages: the PID gains, the damping and a Coulomb level together, on the decimated
    sliding rows, for every derivative filter of ``settings.filter_steps`` and command delay of
    ``settings.delay_steps``; then, under each of the ``n_best`` loops, the damping and the friction
    of ``effects`` again at the full rate (:func:`_plant_by_equation_error`). The damping and
    the derivative gain are nearly collinear (both act on the velocity): the loop keeps their
    sum, the second stage splits what the loop leaves.

    Parameters
    ----------
    prep : Prepared
        The run (its position, reference, filtered derivatives and sliding rows).
    b : Bounds
        Its parameter ranges (the Stribeck velocities tried).
    effects : sequence of str
        ``("coulomb_friction",)`` or ``("coulomb_friction", "stribeck_friction")``.
    n_best : int
        Fits returned, best first, at most one per delay.
    mask : ndarray of bool, shape (K,), optional
        The samples the fit may use (a training fold: a start for a held-out test must not
        have seen the held-out samples); default all.
    delays : sequence of int
        Command delays tried, log samples (default ``settings.delay_steps``; a model whose delay is
        already set gives its own).

    Returns
    -------
    list of EquationErrorFit
        Empty when no grid point gives a loop with a positive derivative gain.
    """
    effects = tuple(effects)
    if effects not in (_FRICTION[:1], _FRICTION):
        raise ValueError(f"effects={effects!r}: expected {_FRICTION[:1]!r} or {_FRICTION!r}")
    if isinstance(n_best, bool) or not isinstance(n_best, int) or n_best < 1:
        raise ValueError(f"n_best={n_best!r}: expected an integer >= 1")
    delays = tuple(defaults().delay_steps if delays is None else delays)
    if not delays or any(isinstance(d, bool) or not isinstance(d, (int, np.integer)) or d < 0
                         for d in delays):
        raise ValueError(f"delays={delays!r}: expected one or more integers >= 0")
    inp = prep.inputs
    ts = inp.ts
    x = np.asarray(prep.x, dtype=float)
    if mask is None:
        mask = np.ones(x.shape[0], dtype=bool)
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != x.shape:
        raise ValueError(f"mask: shape {mask.shape}, expected {x.shape} (one flag per sample)")
    if x.shape[0] < 30:
        return []
    e = inp.xr - x
    cols = {"e": e, "vr": inp.vr, "ar": inp.ar,
            "dx": np.diff(x, prepend=x[0] - inp.v0 * ts) / ts,
            "s_e": ts * np.concatenate([[0.0], np.cumsum(e)[:-1]])}
    bb, aa = signal.butter(4, min(prep.cutoff_hz * 2.0 * ts, 0.99))
    pad = min(3 * max(len(aa), len(bb)), x.shape[0] - 1)

    def lowpass(c: np.ndarray) -> np.ndarray:
        # the filter the measured acceleration went through, so that both sides match
        return signal.filtfilt(bb, aa, c, axis=0, padlen=pad)

    rows = prep.sliding_dec & mask[::prep.decim][:prep.sliding_dec.shape[0]]
    if np.count_nonzero(rows) < 20:
        return []
    lhs = decimate_columns(prep.af, prep.decim)[rows]
    plant = decimate_columns(np.column_stack([-prep.vf, -np.sign(prep.vf)]), prep.decim)[rows]
    fixed = lowpass(np.column_stack([e, cols["s_e"], inp.ar, np.ones_like(e)]))
    best: dict[int, tuple[float, CascadeController, float]] = {}
    for steps in defaults().filter_steps:
        pole = steps / (steps + 1.0)
        f_vr = _first_order(inp.vr, pole)
        filt = lowpass(np.column_stack([f_vr, _first_order(cols["dx"], pole),
                                        _running_integral(f_vr, ts)]))
        ctrl_cols = np.column_stack([fixed[:, 0], filt[:, 0], -filt[:, 1], fixed[:, 1],
                                     fixed[:, 2], fixed[:, 3], filt[:, 2]])
        for d in delays:
            d = int(d)
            X = np.hstack([decimate_columns(_shifted(ctrl_cols, d), prep.decim)[rows], plant])
            # wv kp, wv (the sign in its column), wv kpi, the damping and the Coulomb level
            # are not negative
            nonneg = np.array([True, False, True, True, False, False, False, True, True])
            coef = solve_ls(X, lhs, nonneg)
            wv = float(coef[2])
            if not (wv > 0.0 and np.all(np.isfinite(coef))):
                continue
            rel = math.sqrt(sumsq(lhs - X @ coef) / max(sumsq(lhs), 1e-300))
            if d in best and best[d][0] <= rel:
                continue
            best[d] = (rel, _law(coef, pole, _feedforward_detected(X, lhs, coef)), steps)
    out: list[EquationErrorFit] = []
    for d, (rel, ctrl, steps) in sorted(best.items(), key=lambda kv: kv[1][0])[:n_best]:
        row = _plant_by_equation_error(prep, b, _command(ctrl, cols, steps, ts), d, effects,
                                       lowpass, mask)
        if row is None:
            continue
        # the filter's time constant carried to the model loop's period
        loop = CascadeController(wv=ctrl.wv, kp=ctrl.kp, ki=ctrl.ki, kvff=ctrl.kvff,
                                 kaff=ctrl.kaff, kpi=ctrl.kpi,
                                 vel_pole=steps * ts / (steps * ts + inp.loop_ts))
        out.append(EquationErrorFit(GreyBox(loop, row, effects), rel, d, steps))
    return out
