"""Compliance: motor and load masses coupled by a spring and a damper.

A flexible coupling, a long ball screw or a belt lets the load (the table) lag the motor: the
axis gains a resonance ``f_r`` (the two masses against each other) and, seen from the motor,
an anti-resonance ``f_a = f_r sqrt(1 - r)`` (the load ringing against a held motor), where
``r = m_L / M`` is the load's share of the mass. The plant (:mod:`fricbench.axis.plant`) holds
the size ``r`` and the shape ``f_r``, ``zeta``. The friction and the damping act on the motor
side (screw bearings, nut and motor: a ball-screw axis) or on the load (a belt's or a long
screw's carriage on its guides; ``compliance_friction_load``): the start tries both and keeps
the better, as it does the sensor's side. The actuator force and cogging stay on the motor.

With one position the sensor is the one fed back: on the motor (semi-closed loop: the motor
encoder) or on the load (full-closed loop: a linear scale); the start tries both and keeps the
better, and the fit keeps that side. With two positions (``--load-position``) the logged
position is the motor's and the second one the load's (:attr:`Prepared.x_load`).

Starts come from the run, not from a guess: the peaks of the residual's spectrum (Welch) and,
with a load encoder, the resonance of the deflection ``x_L - x_M`` measured directly, each
tried at a few load shares by simulation.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy import signal

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.effects.base import Effect, Probe, SimulateFn
from fricbench.sysid.diagnose.leastsq import sumsq
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared
from fricbench.sysid.diagnose.settings import defaults

if TYPE_CHECKING:
    from fricbench.sysid.diagnose.models import GreyBox

__all__ = ["Compliance", "resonance_candidates", "deflection_resonance", "frequency_range",
           "frf_candidates"]


def frequency_range(b: Bounds) -> tuple[float, float]:
    """Resonances a run can show, Hz: ``settings.compliance_min_cycles`` in its duration, up to
    0.45 x sampling."""
    return max(0.5, defaults().compliance_min_cycles / max(b.duration, 1e-9)), 0.45 / b.ts


def resonance_candidates(r: np.ndarray, ts: float, f_lo: float, f_hi: float,
                         n_best: int = 3) -> list[float]:
    """Frequencies (Hz) of the strongest peaks of the spectrum of a residual ``r``.

    Welch's estimate (Hann segments of about 1 s, at least 256 samples) of the residual's
    *velocity* (``f^2`` times its power: the slow part of a position residual, a friction lag
    or a drift, would hide any ringing); the peaks within ``[f_lo, f_hi]`` are ranked by
    prominence (in decades above their surroundings) and refined by a parabola.
    """
    r = np.asarray(r, dtype=float)
    if r.size < 64 or not np.all(np.isfinite(r)) or not np.any(r != r[0]):
        return []
    nper = int(min(r.size, max(256, round(1.0 / ts))))
    f, pxx = signal.welch(r - np.mean(r), fs=1.0 / ts, nperseg=nper, detrend="linear")
    spec = np.log10(pxx * f**2 + 1e-300)
    band = (f >= f_lo) & (f <= f_hi)
    if np.count_nonzero(band) < 3:
        return []
    idx, props = signal.find_peaks(np.where(band, spec, -np.inf), prominence=0.3)
    if idx.size == 0:
        return []
    order = np.argsort(props["prominences"])[::-1][:n_best]
    out = []
    df = f[1] - f[0]
    for k in idx[order]:
        a, b_, c = spec[k - 1], spec[k], spec[k + 1]
        den = a - 2.0 * b_ + c
        shift = 0.5 * (a - c) / den if den < 0.0 else 0.0
        out.append(float(f[k] + float(np.clip(shift, -0.5, 0.5)) * df))
    return out


def deflection_resonance(x_motor: np.ndarray, x_load: np.ndarray, ts: float, f_lo: float,
                         f_hi: float) -> tuple[float, float] | None:
    """Anti-resonance ``f_a`` (Hz) and its damping ratio from two encoders, by least squares.

    The deflection ``d = x_L - x_M`` obeys ``d'' + 2 zeta_a w_a d' + w_a^2 d = -a_M - F_L / m_L``
    whatever drives the motor (the load's own equation), ``F_L`` the load's friction and
    damping when they act on it (a belt's carriage): ``F_c sign(v_L) + B_L v_L``. So the
    deflection's derivatives, the motor's acceleration and those two columns of the load's
    velocity (central differences of low-passed signals) give ``w_a^2`` and ``2 zeta_a w_a``
    linearly, whichever body the friction acts on (its columns' coefficients are then about
    zero). Returns None when the fit is not physical (no positive stiffness) or out of range.
    """
    fc = min(0.4 / ts, 4.0 * f_hi)
    b, a = signal.butter(4, min(fc * 2.0 * ts, 0.95))
    d = signal.filtfilt(b, a, np.asarray(x_load, float) - np.asarray(x_motor, float))
    xm = signal.filtfilt(b, a, np.asarray(x_motor, float))
    dv = np.gradient(d, ts)
    da = np.gradient(dv, ts)
    vm = np.gradient(xm, ts)
    am = np.gradient(vm, ts)
    vl = vm + dv
    edge = slice(20, -20) if d.size > 100 else slice(None)
    X = np.column_stack([d[edge], dv[edge], np.sign(vl[edge]), vl[edge]])
    y = -(da + am)[edge]
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(y))) or sumsq(X[:, 0]) <= 0.0:
        return None
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    wa2, c2 = float(coef[0]), float(coef[1])
    if not wa2 > 0.0:
        return None
    wa = math.sqrt(wa2)
    f_a = wa / (2.0 * math.pi)
    if not f_lo <= f_a <= f_hi:
        return None
    return f_a, float(np.clip(c2 / (2.0 * wa), *defaults().compliance_zeta_range))


def frf_candidates(effort: np.ndarray, y: np.ndarray, ts: float, f_lo: float, f_hi: float,
                   n_best: int = 2) -> list[tuple[float, float | None]]:
    """Resonances in the frequency response of an open-loop run, Hz, with the load share
    their anti-resonance gives (or None without one).

    ``G = S_uy / S_uu`` (Welch, segments of about 1 s); a rigid mass gives a flat
    ``w^2 |G| = 1 / M``, a compliant axis a peak at ``f_r`` and, seen from the motor, a dip at
    ``f_a = f_r sqrt(1 - r)`` below it.
    """
    u = np.asarray(effort, float)
    x = np.asarray(y, float)
    if u.size < 64 or not (np.all(np.isfinite(u)) and np.all(np.isfinite(x))):
        return []
    nper = int(min(u.size, max(256, round(1.0 / ts))))
    f, puu = signal.welch(u, fs=1.0 / ts, nperseg=nper, detrend="linear")
    _, pyy = signal.welch(x, fs=1.0 / ts, nperseg=nper, detrend="linear")
    _, puy = signal.csd(u, x, fs=1.0 / ts, nperseg=nper, detrend="linear")
    # the excited band (where the effort has power), and within it the frequencies where the
    # position follows the effort (coherence): a peak elsewhere is noise over no input
    excited = (f >= f_lo) & (f <= f_hi) & (puu > defaults().compliance_excited_share * np.max(puu))
    coh = np.abs(puy) ** 2 / np.maximum(puu * pyy, 1e-300)
    if np.count_nonzero(excited) < 3:
        return []
    mag = np.log10(np.abs(puy) / np.maximum(puu, 1e-300) * (2.0 * np.pi * f) ** 2 + 1e-300)
    peaks, props = signal.find_peaks(np.where(excited & (coh > defaults().compliance_min_coherence),
                                              mag, -np.inf),
                                     prominence=0.2)
    dips, _ = signal.find_peaks(np.where(excited, -mag, -np.inf), prominence=0.2)
    out: list[tuple[float, float | None]] = []
    for k in peaks[np.argsort(props["prominences"])[::-1][:n_best]]:
        below = [d for d in dips if 0.2 * f[k] < f[d] < f[k]]
        ratio = None
        if below:
            d = max(below, key=lambda j: -mag[j])
            ratio = float(np.clip(1.0 - (f[d] / f[k]) ** 2, 0.02, 0.9))
        out.append((float(f[k]), ratio))
    return out


def rigid_from_frf(effort: np.ndarray, y: np.ndarray, ts: float, f_lo: float,
                   f_hi: float) -> tuple[float, float] | None:
    """Mass and viscous damping of the rigid body below ``f_hi``, from the frequency
    response: ``1 / G = -M w^2 + j B w`` by least squares on the coherent, excited bins.

    Below a resonance the two masses move as one, so this start of ``M`` and ``B`` does not
    suffer the resonance's phase the way filtered inverse dynamics does."""
    u = np.asarray(effort, float)
    x = np.asarray(y, float)
    nper = int(min(u.size, max(256, round(1.0 / ts))))
    f, puu = signal.welch(u, fs=1.0 / ts, nperseg=nper, detrend="linear")
    _, pyy = signal.welch(x, fs=1.0 / ts, nperseg=nper, detrend="linear")
    _, puy = signal.csd(u, x, fs=1.0 / ts, nperseg=nper, detrend="linear")
    coh = np.abs(puy) ** 2 / np.maximum(puu * pyy, 1e-300)
    sel = ((f > max(f_lo, 0.0)) & (f <= f_hi)
           & (puu > defaults().compliance_excited_share * np.max(puu))
           & (coh > defaults().compliance_min_coherence) & (np.abs(puy) > 0.0))
    if np.count_nonzero(sel) < 3:
        return None
    w = 2.0 * np.pi * f[sel]
    inv_g = puu[sel] / puy[sel]
    # Re(1/G) = -M w^2, Im(1/G) = B w (one column each, weighted to relative errors)
    m = float(-np.sum(inv_g.real * w**2) / np.sum(w**4))
    b = float(np.sum(inv_g.imag * w) / np.sum(w**2))
    if not (math.isfinite(m) and m > 0.0 and math.isfinite(b)):
        return None
    return m, max(b, 0.0)


class Compliance(Effect):
    """Two masses on a spring and a damper: ``m_M a_M = F - F_f + k d + c d'``,
    ``m_L a_L = -k d - c d'`` (``d = x_L - x_M``); parameters ``r = m_L / M``, ``f_r``, ``zeta``.
    """

    name = "compliance"
    kind = "output"
    summary = ("a compliant coupling: motor and load masses on a spring and a damper (a "
               "resonance and an anti-resonance)")
    parameters = (CL.I_CR, CL.I_CF, CL.I_CZ)
    shape_parameters = (CL.I_CF, CL.I_CZ)
    periodic = False
    # fitted for real when its linearised screen (a two-mass probe at the residual's spectral
    # peaks) ranks it among the confirmed candidates, as a backlash or a drift is (friction and
    # the cogging stay always fitted: their screens miss how stick-slip moves the stops). Fitted
    # at every step whatever its screen, its fold fits took 38 % of a 40k-sample diagnosis where
    # it was rejected each time, and no held-out run of either simulator changed without them
    always_fitted = False
    refits_mass = True

    def available(self, prep: Prepared) -> bool:
        # the run must span settings.compliance_min_cycles of a resonance below the top of the band
        return prep.duration * 0.45 / prep.ts >= 2.0 * defaults().compliance_min_cycles

    def bounds(self, i: int, value: float, b: Bounds) -> Param:
        if i == CL.I_CF:
            lo, hi = frequency_range(b)
            return Param(i, True, lo, hi, 1.0)
        if i == CL.I_CZ:
            zeta = defaults().compliance_zeta_range
            return Param(i, True, zeta[0], zeta[1], 1.0)
        if i == CL.I_COMP_B_MOTOR:
            # a share: all of B on the load (0) or on the motor (1) are both real axes
            return Param(i, False, 0.0, 1.0, 0.25)
        return Param(i, False, 0.0, 0.95, 0.1)

    def clip(self, i: int, value: float, b: Bounds) -> float:
        if i == CL.I_CF:
            lo, hi = frequency_range(b)
            return float(np.clip(value, 1.05 * lo, 0.95 * hi))
        if i == CL.I_CZ:
            zeta = defaults().compliance_zeta_range
            return float(np.clip(value, 1.5 * zeta[0], 0.5 * zeta[1]))
        if i == CL.I_COMP_B_MOTOR:
            return float(np.clip(value, 0.0, 1.0))
        return float(np.clip(value, 0.02, 0.9))

    def probe_step(self, i: int, value: float, b: Bounds) -> float:
        return 0.1 if i == CL.I_CR else 0.05 * abs(value)

    def conditional(self, p: np.ndarray) -> tuple[int, ...]:
        # with the friction on the load, the damping B is split between the two bodies' bearings
        # (the carriage's guides, the pulleys and the motor): all of it on one body leaves the
        # coupling's damping zeta to make up for the other's
        return (CL.I_COMP_B_MOTOR,) if p[CL.I_COMP_LOAD] > 0.5 else ()

    def held(self, p: np.ndarray) -> tuple[int, ...]:
        # with the friction and most of B on the load, the load's own damping B_L / m_L damps
        # the deflection beside the coupling's c: the two are not told apart (on the third
        # simulator's belt tuning runs zeta ran to either bound of its range, to 2 when let,
        # for x0.01..x0.6 held-out gains), so zeta stays at the start's typical coupling
        return (CL.I_CZ,) if p[CL.I_COMP_LOAD] > 0.5 else ()

    def switched_on(self, p: np.ndarray, prep: Prepared) -> np.ndarray:
        q = p.copy()
        # the one position is the fed-back one (a semi-closed loop until the start says)
        q[CL.I_LOG_MOTOR] = 1.0
        q[CL.I_MEAS_TABLE] = 0.0
        if q[CL.I_CR] <= 0.0:
            q[CL.I_CR] = defaults().compliance_start_ratios[0]
        return q

    def zeroed(self, p: np.ndarray, effects: Sequence[str]) -> np.ndarray:
        q = super().zeroed(p, effects)
        # the rigid axis of the diagnosis: feedback from the motor, the table logged
        q[CL.I_LOG_MOTOR] = 0.0
        q[CL.I_MEAS_TABLE] = 0.0
        q[CL.I_COMP_LOAD] = 0.0
        q[CL.I_COMP_B_MOTOR] = 0.0
        return q

    def _frequencies(self, prep: Prepared, b: Bounds, y: np.ndarray) -> list[float]:
        lo, hi = frequency_range(b)
        out: list[float] = []
        if prep.x_load is not None:
            found = deflection_resonance(prep.x, prep.x_load, prep.ts, lo, hi)
            if found is not None:
                # f_r = f_a / sqrt(1 - r): the shares of the starts give the resonance
                out.append(found[0])
        out += resonance_candidates(prep.x - y, prep.ts, lo, hi)
        return [f for k, f in enumerate(out) if all(abs(f / g - 1.0) > 0.02 for g in out[:k])]

    def probes(self, p: np.ndarray, effects: Sequence[str], prep: Prepared, b: Bounds,
               y: np.ndarray) -> list[Probe]:
        cfg = defaults()
        return [({CL.I_CR: cfg.compliance_start_ratios[0]},
                 {CL.I_CF: f, CL.I_CZ: cfg.compliance_start_zeta})
                for f in self._frequencies(prep, b, y)[:2]]

    def output_start(self, model: GreyBox, prep: Prepared, b: Bounds, w: np.ndarray | None,
                     y: np.ndarray, mask: np.ndarray, simulate: SimulateFn) -> GreyBox:
        """The best start on ``mask``, by simulation, of the spectral peaks at a few load
        shares and both sensor sides (one position) or the motor side (two positions).

        Without an effort the loop is a cascade fitted to the position, and a rigid loop fitted
        to a compliant axis is far off (it slows down to follow the ringing): the start is then
        sought under the standard starting loops too, and refined with the loop free on
        ``mask`` (the search judges it on the other samples).
        """
        from fricbench.sysid.diagnose.baselines import (
            starting_controllers,
            starting_pid_controllers,
        )
        from fricbench.sysid.diagnose.controllers import CascadeController
        from fricbench.sysid.diagnose.models import PositionFit, position_params, simulate_models

        if not float(model.plant[CL.I_M]) > 0.0:
            # no positive mass to split (an inverse dynamics that failed): nothing to start
            return model
        freqs = self._frequencies(prep, b, y)
        lo, hi = frequency_range(b)
        if not freqs:
            freqs = list(np.geomspace(max(lo, 2.0), 0.5 * hi, 4))
        sides = ((1.0, 0.0),) if prep.x_load is not None else ((1.0, 0.0), (0.0, 1.0))
        # the friction on the motor, or (told apart only by a load encoder, which sees the
        # load's own friction) on the load with a share of B on the motor
        bodies = [(0.0, 0.0)]
        if prep.x_load is not None:
            bodies += [(1.0, s) for s in defaults().compliance_start_b_motor_shares]
        cascade = isinstance(model.controller, CascadeController)
        # the standard loops of the model's own family (a PID model stays a PID)
        ctrl = model.controller
        standard = (starting_pid_controllers
                    if isinstance(ctrl, CascadeController) and ctrl.is_pid
                    else starting_controllers)
        loops = [model.controller] + (standard(prep.inputs.loop_ts) if cascade else [])
        rows = []
        for f in freqs[:3]:
            for ratio in defaults().compliance_start_ratios:
                # a peak lies between the anti-resonance and the resonance
                for f_r in (f, f / math.sqrt(1.0 - ratio)):
                    if not lo < f_r < hi:
                        continue
                    for (log_motor, table), (on_load, b_motor) in itertools.product(
                            sides, bodies):
                        q = model.plant.copy()
                        q[CL.I_CR], q[CL.I_CF], q[CL.I_CZ] = (ratio, f_r,
                                                              defaults().compliance_start_zeta)
                        q[CL.I_LOG_MOTOR], q[CL.I_MEAS_TABLE] = log_motor, table
                        # the friction and the damping on the motor or on the load (with a
                        # share of the damping on the motor)
                        q[CL.I_COMP_LOAD], q[CL.I_COMP_B_MOTOR] = on_load, b_motor
                        rows.append(q)
        if not rows:
            return model

        def masked_sse(models: list[GreyBox]) -> np.ndarray:
            if prep.x_load is None:
                ys, _, _ = simulate(models, prep, w)
                loads = None
            else:
                # a load encoder: the start is ranked on both positions, as the fit is
                # (PositionFit); the deflection shows most on the load's, where the loop does
                # not hold it down
                loads = np.empty((len(models), prep.n))
                ys, _, _ = simulate_models(models, prep, w, other=loads, effort=False)
            out = np.full(len(models), math.inf)
            for k, yy in enumerate(ys):
                r = (prep.x - yy)[mask]
                if loads is not None:
                    r = np.concatenate([r, (prep.x_load - loads[k])[mask]])
                if np.all(np.isfinite(r)):
                    out[k] = sumsq(r)
            return out

        # the shapes ranked under the current loop, then only the best few under every
        # starting loop (all shapes under all loops is 25 times the simulations, and the
        # shape's rank under the current loop keeps the right one among the first few on the
        # two-mass runs)
        models = [model.copy(plant=q) for q in rows]
        sse = masked_sse(models)
        if len(loops) > 1:
            keep = [rows[k] for k in np.argsort(sse)[:defaults().compliance_start_shapes_per_loop]]
            more = [model.copy(plant=q, controller=loop) for loop in loops[1:] for q in keep]
            models += more
            sse = np.concatenate([sse, masked_sse(more)])
        best = models[int(np.argmin(sse))]
        if not cascade:
            return best
        params = position_params(best, b, controller=True, effects=[self.name])
        return PositionFit(prep, params, mask, w).run(
            best, max_iter=defaults().compliance_start_iterations).model

    def open_loop_starts(self, effort: np.ndarray, y: np.ndarray, ts: float
                         ) -> list[dict[int, float]]:
        """The frequency response's resonances: on a motor encoder at the load share of their
        anti-resonance (else at a few shares), on a load-side sensor at a few shares; with
        the rigid body's mass and damping from the response below them."""
        lo = max(0.5, defaults().compliance_min_cycles / max(y.size * ts, 1e-9))
        out: list[dict[int, float]] = []
        for f_r, ratio in frf_candidates(effort, y, ts, lo, 0.45 / ts):
            # a motor encoder sees the anti-resonance, whose depth gives the load share; a
            # load-side sensor sees none (a dip may be noise): both are tried
            pairs = [(r, 0.0) for r in defaults().compliance_start_ratios]
            pairs += ([(ratio, 1.0)] if ratio is not None
                      else [(r, 1.0) for r in defaults().compliance_start_ratios])
            # the rigid body from the response well below the resonance (and anti-resonance)
            rigid = rigid_from_frf(effort, y, ts, 0.0, 0.3 * f_r)
            body = {CL.I_M: rigid[0], CL.I_B: rigid[1]} if rigid is not None else {}
            out += [{CL.I_CR: r, CL.I_CF: f_r, CL.I_CZ: defaults().compliance_start_zeta,
                     CL.I_LOG_MOTOR: side,
                     **body} for r, side in pairs]
        return out

    def evidence(self, model: GreyBox, prep: Prepared, w: np.ndarray | None,
                 simulate: SimulateFn) -> str | None:
        """The resonance must be where the residual fell: the rigid model's residual rings in
        the band ``0.7 f_a .. 1.3 f_r`` and the compliant one removes most of that ringing
        (at most ``1 - settings.explained_share`` of it left in the band, and at least
        ``settings.explained_share`` of the whole fall of the residual power there: the larger
        part of each; Welch spectra of the residuals, weighted by ``f^2`` like
        :func:`resonance_candidates`)."""
        p = model.plant
        f_r = float(p[CL.I_CF])
        f_a = f_r * math.sqrt(max(1.0 - float(p[CL.I_CR]), 0.0))
        pair = [model, model.without(self.name)]
        nper = int(min(prep.n, max(256, round(1.0 / prep.ts))))
        cfg = defaults()
        if prep.x_load is not None:
            return self._deflection_evidence(pair, prep, w, nper)
        ys, _, _ = simulate(pair, prep, w)
        power = []
        for y in ys:
            r = prep.x - y
            if not np.all(np.isfinite(r)):
                return None  # a diverging loop is rejected by the search itself
            f, pxx = signal.welch(r - np.mean(r), fs=1.0 / prep.ts, nperseg=nper,
                                  detrend="linear")
            power.append(pxx * f**2)
        p_with, p_rigid = power
        band = (f >= 0.7 * f_a) & (f <= 1.3 * f_r)
        rigid_band = float(np.sum(p_rigid[band]))
        if not np.any(band) or rigid_band <= 0.0:
            return (f"{self.name}: its band {0.7 * f_a:.3g} .. {1.3 * f_r:.3g} Hz holds no "
                    "residual of the rigid model")
        left = float(np.sum(p_with[band])) / rigid_band
        fall = float(np.sum(p_rigid - p_with))
        share = float(np.sum(p_rigid[band] - p_with[band])) / fall if fall > 0.0 else -1.0
        if left > 1.0 - cfg.explained_share or share < cfg.explained_share:
            return (f"{self.name}: the fitted resonance ({f_a:.3g} .. {f_r:.3g} Hz) is not "
                    f"where the residual fell ({100.0 * left:.0f} % of the rigid model's "
                    f"residual left in its band, {100.0 * share:.0f} % of the fall there): a "
                    "flexible model standing in for another mismatch")
        return None

    def _deflection_evidence(self, pair: list[GreyBox], prep: Prepared, w: np.ndarray | None,
                             nper: int) -> str | None:
        """With a load encoder the coupling's deflection ``x_L - x_M`` is measured: the
        compliant model must explain the larger part of it (at most
        ``1 - settings.explained_share`` of its power left in the deflection's residual), where
        the rigid model predicts none.
        Under a loop tuned below the resonance the deflection is mostly the quasi-static lag
        ``F / k`` of the load, not a ringing, so the band test of the motor's residual would
        miss it; and its power is not weighted by ``f^2`` as the band test's is, which would
        make it the encoders' noise."""
        from fricbench.sysid.diagnose.models import simulate_models

        assert prep.x_load is not None
        loads = np.empty((2, prep.n))
        ys, _, _ = simulate_models(pair, prep, w, other=loads, effort=False)
        d_meas = prep.x_load - prep.x
        power = []
        for y, yl in zip(ys, loads, strict=True):
            r = d_meas - (yl - y)
            if not np.all(np.isfinite(r)):
                return None  # a diverging loop is rejected by the search itself
            _, pxx = signal.welch(r - np.mean(r), fs=1.0 / prep.ts, nperseg=nper,
                                  detrend="linear")
            power.append(float(np.sum(pxx)))
        p_with, p_rigid = power
        if p_rigid <= 0.0:
            return f"{self.name}: the two encoders show no deflection"
        left = p_with / p_rigid
        if left > 1.0 - defaults().explained_share:
            return (f"{self.name}: the fitted coupling leaves {100.0 * left:.0f} % of the "
                    "measured deflection between the two encoders: a flexible model standing in "
                    "for another mismatch")
        return None

    def describe(self, p: np.ndarray, force_unit: str) -> dict[str, float]:
        ratio, f_r = float(p[CL.I_CR]), float(p[CL.I_CF])
        return {"load_fraction": ratio, "f_r_hz": f_r,
                "f_a_hz": f_r * math.sqrt(max(1.0 - ratio, 0.0)),
                "zeta": float(p[CL.I_CZ]),
                # 1: that position is the load's, 0: the motor's
                "logged_on_load": 1.0 - float(p[CL.I_LOG_MOTOR]),
                "feedback_on_load": float(p[CL.I_MEAS_TABLE]),
                # 1: the friction and the damping act on the load, 0: on the motor
                "friction_on_load": float(p[CL.I_COMP_LOAD]),
                # with the friction on the load: the share of the damping B on the motor
                "damping_motor_share": float(p[CL.I_COMP_B_MOTOR])}
