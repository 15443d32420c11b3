"""The linear starting models: a black-box closed-loop transfer function, the linear grey-box
loop (controller + mass with viscous damping) and the linear inverse dynamics."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.controllers import (
    ArxController,
    CascadeController,
    fit_arx_controller,
)
from fricbench.sysid.diagnose.criterion import comparison_samples, criterion_change
from fricbench.sysid.diagnose.effects import get_effect
from fricbench.sysid.diagnose.equation_error import delay_steps, loop_by_equation_error
from fricbench.sysid.diagnose.models import (
    Bounds,
    GreyBox,
    InverseDynamics,
    Param,
    PositionFit,
    PositionFitResult,
    cascade_effort,
    position_params,
    race_fits,
    simulate_inputs,
    simulate_models,
)
from fricbench.sysid.diagnose.prepared import Prepared
from fricbench.sysid.diagnose.settings import defaults
from fricbench.sysid.tf_fit import fit_tf, simulate_tf

__all__ = ["LinearTF", "fit_law", "fit_law_like", "law_relerr_floor",
           "fit_linear_tf", "fit_linear_cascade", "fit_linear_with_effort", "fit_law_and_delay",
           "force_scale", "starting_controllers", "friction_aware_loop",
           "friction_aware_fit_scaled", "coulomb_starts"]


@dataclass
class LinearTF:
    """Black-box reference-to-position transfer function and its free-run position.

    Attributes
    ----------
    tf : control.TransferFunction or None
        Continuous-time model (None when the fit failed).
    y : ndarray or None
        Its free-run position on the run, m.
    order : tuple of int
        (poles, zeros).
    """

    tf: object
    y: np.ndarray | None
    order: tuple[int, int]


def fit_linear_tf(prep: Prepared, orders: tuple[tuple[int, int], ...] = ((2, 1), (3, 2))
                  ) -> LinearTF:
    """Fit ``fricbench.sysid.tf_fit.fit_tf`` of each order; keep the best free-run fit."""
    best: LinearTF | None = None
    best_sse = np.inf
    for n_poles, n_zeros in orders:
        try:
            tf = fit_tf(prep.run.x_ref, prep.x, prep.ts, n_poles=n_poles, n_zeros=n_zeros,
                        max_nfev=100)
            y = simulate_tf(tf, prep.run.x_ref, prep.ts)
        except (ValueError, np.linalg.LinAlgError, FloatingPointError):
            continue
        sse = float(np.sum((prep.x - y) ** 2))
        if np.isfinite(sse) and sse < best_sse:
            best, best_sse = LinearTF(tf, y, (n_poles, n_zeros)), sse
    return best if best is not None else LinearTF(None, None, (0, 0))


def force_scale(u: np.ndarray, ts: float) -> float:
    """A robust magnitude of an effort: the 99th percentile of its low-passed absolute value."""
    from scipy import signal

    b, a = signal.butter(2, min(0.9, 2 * ts * 50.0))
    uf = signal.filtfilt(b, a, u)
    return float(max(np.percentile(np.abs(uf), 99), 1e-12))


def reference_acceleration(prep: Prepared) -> float:
    """The reference's largest acceleration (absolute), m/s^2 or rad/s^2: the motion's
    inertial force per unit mass, the run's smallest force scale."""
    return float(np.max(np.abs(prep.inputs.ar)))


def starting_controllers(ts: float) -> list[CascadeController]:
    """Standard starting loops: velocity bandwidths of 8, 25 and 60 % of the sampling rate,
    position gain 8 or 30 % of it, with and without integral action and feedforward."""
    out = []
    for wv_ts, kp_frac, ki_frac, kvff in itertools.product(
            (0.08, 0.25, 0.6), (0.08, 0.3), (0.0, 0.1), (0.0, 1.0)):
        wv = wv_ts / ts
        out.append(CascadeController(wv=wv, kp=kp_frac * wv, ki=ki_frac * wv, kvff=kvff))
    return out


def starting_pid_controllers(ts: float) -> list[CascadeController]:
    """Standard starting PID position loops (:attr:`CascadeController.is_pid`): derivative
    gains of 8, 25 and 60 % of the sampling rate, proportional gain 10 or 30 % of it, integral
    1 or 4 % of its square, derivative unfiltered or through a filter of about 2 samples."""
    out = []
    for wv_ts, kp_frac, kpi_frac, pole in itertools.product(
            (0.08, 0.25, 0.6), (0.1, 0.3), (0.01, 0.04), (0.0, 0.7)):
        wv = wv_ts / ts
        out.append(CascadeController(wv=wv, kp=kp_frac * wv, kvff=1.0, kpi=kpi_frac * wv * wv,
                                     vel_pole=pole))
    return out


def fit_linear_cascade(prep: Prepared, n_best: int = 2, max_iter: int = 15
                       ) -> tuple[GreyBox, np.ndarray, Bounds, np.ndarray | None]:
    """Linear grey-box loop without effort: a cascade controller on a unit mass.

    Several starting controllers (velocity bandwidths from 8 % to 60 % of the sampling rate,
    with and without integral action and feedforward) are simulated; the best few are refined
    by output error and the best refinement is returned (a base fit that has not converged
    would make any added effect look useful).

    Returns
    -------
    model : GreyBox
    y : ndarray
        Its free-run position, m.
    bounds : Bounds
        Parameter ranges of the run (the force scale from the model's virtual effort).
    jac_rows : ndarray or None
        Jacobian of the fit, one row per parameter.
    """
    starts = [GreyBox(c, CL.default_plant(1.0, 0.0))
              for c in starting_controllers(prep.inputs.loop_ts)]
    ys, _, status = simulate_models(starts, prep)
    sse = np.array([np.sum((prep.x - y) ** 2) if s == 0 and np.all(np.isfinite(y)) else np.inf
                    for y, s in zip(ys, status, strict=True)])
    order = np.argsort(sse)[:n_best]
    f0 = max(reference_acceleration(prep), 1e-6)
    b0 = Bounds(force=f0, stroke=max(prep.stroke, 1e-9), v_max=max(prep.v_max, 1e-9),
                duration=prep.duration, ts=prep.ts, noise=prep.noise.rms,
                loop_ts=prep.inputs.loop_ts, rotary=prep.rotary)
    best = None
    for i in order:
        if not np.isfinite(sse[i]):
            continue
        m = starts[i]
        fit = PositionFit(prep, position_params(m, b0, controller=True))
        res = fit.run(m, max_iter=max_iter, jacobian=True)  # the screen's columns
        if best is None or res.cost < best.cost:
            best = res
    if best is None:
        raise ValueError("no linear closed-loop model could be simulated stably on this run")
    u_virtual = cascade_effort(best.model.controller, prep)
    bounds = replace(b0, force=max(force_scale(u_virtual, prep.ts), f0))
    return best.model, best.y, bounds, best.jac_rows


@dataclass(frozen=True)
class DriveLimit:
    """A drive limit identified from a run without an effort.

    Attributes
    ----------
    level : float
        The limit of the loop's command, per unit mass (m/s^2).
    clipped_share : float
        Share of the samples the fitted loop clips.
    sse_ratio : float
        Squared position error with the limit over the error without it (loop and Coulomb
        friction refitted both ways).
    model : GreyBox
        The loop, Coulomb force and limit fitted together.
    """

    level: float
    clipped_share: float
    sse_ratio: float
    model: GreyBox


def fit_drive_limit(fit: PositionFitResult, prep: Prepared, bounds: Bounds,
                    **options: int) -> DriveLimit | None:
    """The drive's command limit, when a run without an effort shows one; else None.

    The first of :func:`drive_limits`, whose options (``max_iter``, ``n_best``) and defaults
    it takes as they are: the diagnosis's own search (a copy of the defaults here drifted
    from them once, and the suite judged a search the diagnosis did not run).
    """
    return drive_limits(fit, prep, bounds, **options)[0]


def drive_limits(fit: PositionFitResult, prep: Prepared, bounds: Bounds,
                 max_iter: int = 15, n_best: int = 2
                 ) -> tuple[DriveLimit | None, DriveLimit | None]:
    """The drive's command limit kept (or None), and else the tentative one (or None).

    A drive that clips its current (a rapid move, a reversal against friction) lags the
    reference in a way no linear loop with friction reproduces: without the effort nothing
    says it clipped. The loop, a Coulomb force and a limit on the loop's command are fitted
    together, and what the run shows of the limit is its headroom (:func:`limit_headroom`):
    while the axis speeds up in the direction it moves, the drive delivers the acceleration,
    the damping's force and the friction's, and a drive that clips delivers no more. The
    clipped moves show the limit minus the friction far better than either (the second
    simulator's control/5: fits as close with a limit and a friction both half the truth), so
    each start is a Coulomb force with the limit the headroom above it: ``fit``'s own model
    (the loop and a Coulomb force fitted without a limit, :func:`friction_aware_fit`), and for
    each Coulomb force of ``settings.limit_friction_grid`` (in units of the headroom) and
    ``fit``'s, the best ``n_best`` of the standard loops of both families and ``fit``'s
    (:func:`_fit_limit`). A drive that clips against a friction as large as the motion's own
    acceleration lags so far that a fit without a limit finds no friction at all (the loop
    alone explains more): ``fit``'s friction is then no start, the grid's are. The headroom
    says nothing of how the limit splits between the friction and what is left, so the grid
    spans that split (the friction a fifth of the limit to nearly all of it). The
    limit is bounded below by the headroom itself, the largest acceleration the axis showed in
    the direction it moved (the drive delivered at least that, the damping and the friction
    opposing it).

    The best fit's limit counts when it clips at least ``settings.rows_per_parameter``
    samples (a limit is one parameter, and the samples it clips are what determine it). It is
    kept when the loop with it leaves less than ``settings.limit_margin`` of the squared error
    without it, and is tentative when it leaves less than that error at all (the criterion
    then decides between the searches with and without it). Like the loop gains the limit is
    a property of the loop the effects are then judged with, not an effect.

    These starts and that floor replaced two searches (a drive sized for the motion, its
    limits 1.5 and 3 times the reference's largest acceleration and at least half of it, and,
    when it kept none, a drive sized for its friction, its limits 1.2, 1.5 and 3 times each
    Coulomb force and at least a tenth of that acceleration: four tuned fields) and a share
    of the samples clipped, 0.5 % (tuned); docs/diagnosis_method.md. The Coulomb forces were
    the friction-aware fit's starts then (0.3 and 1 times the reference's largest
    acceleration, tuned for that fit) until the grid: a drive sized for its friction clips against
    a force several times the motion's, which those starts did not reach (the second
    simulator's development runs: the friction 1 to 5 times the headroom).
    """
    a_ref = reference_acceleration(prep)
    if not (a_ref > 0.0 and fit.cost > 0.0) or np.isfinite(fit.model.plant[CL.I_IMAX]):
        return None, None
    headroom = limit_headroom(prep)
    if not headroom > 0.0:
        return None, None
    cfg = defaults()
    # in units of a_ref, as the Coulomb starts are
    fitted = (float(fit.model.plant[CL.I_FC]) / a_ref
              if "coulomb_friction" in fit.model.effects else 0.0)
    # the friction the fit without a limit found is a start too: a drive sized for its
    # friction clips just above it, however it compares with the motion's acceleration (the
    # second simulator's control/28: a PID whose limit is 1.3 times a Coulomb force of 2.9
    # times the reference's largest acceleration; the loop fitted without the limit left
    # 12.6 um, 450 floors, and a false cogging cut that 2.7x)
    levels = sorted({*(g * headroom / a_ref for g in cfg.limit_friction_grid),
                     *([fitted] if fitted > 0.0 else [])})
    loops = ([fit.model.controller] + list(starting_controllers(prep.inputs.loop_ts))
             + list(starting_pid_controllers(prep.inputs.loop_ts)))
    own = fit.model.copy()
    own.plant[CL.I_IMAX] = (fitted + headroom / a_ref) * a_ref
    found = _fit_limit(fit, prep, bounds, own, a_ref,
                       [(f, f + headroom / a_ref) for f in levels], headroom / a_ref,
                       max_iter, n_best, loops)
    if found is None or not found.sse_ratio < 1.0:
        return None, None
    if found.sse_ratio < cfg.limit_margin:
        return found, None
    # a limit that lowers the error at all is tried: the criterion then decides between the
    # searches with and without it (this was a field, limit_tentative, whose value 1 meant that)
    return None, found


def limit_headroom(prep: Prepared) -> float:
    """What a run without an effort shows of its drive's limit, per unit mass: the largest
    filtered acceleration while the axis speeds up in the direction it moves (0 when it never
    does).

    There the drive delivers the acceleration, the damping's force and the friction's, and a
    drive that clips delivers no more: the limit minus the friction and the damping's force
    when the drive clipped there, a lower bound of the limit whatever the drive. The damping's
    force is left out: a loop fitted without a limit puts the clipping's lag into its damping
    (the second simulator's control/12: 58 1/s against the truth's 0.43).
    """
    speeding_up = prep.af * prep.vf > 0.0
    return float(np.max(np.abs(prep.af[speeding_up]))) if np.any(speeding_up) else 0.0


def _fit_limit(fit: PositionFitResult, prep: Prepared, bounds: Bounds, own: GreyBox,
               a_ref: float, pairs: Sequence[tuple[float, float]], lowest: float,
               max_iter: int, n_best: int,
               loops: Sequence[CascadeController | ArxController]
               ) -> DriveLimit | None:
    """The search of :func:`drive_limits`: fits of the loop, a Coulomb force and the limit
    (bounded below by ``lowest``) from ``own`` and, for each ``(Coulomb force, limit)`` of
    ``pairs``, from the ``n_best`` of ``loops`` that start closest to the run; forces in
    units of ``a_ref``, the reference's largest acceleration.
    The best fit's limit when it clips at least ``settings.rows_per_parameter`` samples, else
    None."""
    limit = Param(CL.I_IMAX, True, lowest * a_ref, max(100.0, 2.0 * lowest) * a_ref, 1.0)
    grid = []
    for ctrl in loops:
        for f_fc, f_lim in pairs:
            # no damping: the one fitted without a limit stands in for the clipping's lag
            m = GreyBox(ctrl, CL.default_plant(1.0, 0.0), ("coulomb_friction",))
            m.plant[CL.I_FC] = f_fc * a_ref
            m.plant[CL.I_IMAX] = f_lim * a_ref
            grid.append(m)
    # ranked with one plant substep per sample instead of prep.n_sub: a ranking of starts
    # (the fits run at prep.n_sub), at half the cost of the grid on a long run
    ys, _, status = simulate_inputs(grid, prep.inputs, 1, effort=False)
    sse = np.array([np.sum((prep.x - y) ** 2) if s == 0 and np.all(np.isfinite(y))
                    else np.inf for y, s in zip(ys, status, strict=True)])
    starts = [own]
    # the best loops of each pair: the pairs are the basins (how the force splits between the
    # friction and the limit), which a ranking of the starts cannot judge
    for j in range(len(pairs)):
        mine = np.argsort(sse[j::len(pairs)], kind="stable")[:n_best] * len(pairs) + j
        starts += [grid[i] for i in mine if np.isfinite(sse[i])]
    # independent fits, on two threads at once (the same numbers), racing: the starts differ
    # in the clip's level and friction, basins a heat of settings.limit_race_share tells
    # apart; only the best heat finishes
    fits = [r for r in race_fits(
        [(PositionFit(prep, position_params(m, bounds, controller=True) + [limit]), m)
         for m in starts], max_iter, share=defaults().limit_race_share) if r is not None]
    best = min(fits, key=lambda r: r.cost) if fits else None
    if best is None or not np.isfinite(best.cost):
        return None
    level = float(best.model.plant[CL.I_IMAX])
    _, u, status = simulate_models([best.model], prep)
    if status[0] != 0 or not np.all(np.isfinite(u[0])):
        return None
    at_limit = np.abs(u[0]) >= level * (1.0 - 1e-9)
    if int(np.count_nonzero(at_limit)) < defaults().rows_per_parameter:
        return None
    return DriveLimit(level, float(np.mean(at_limit)), float(best.cost / fit.cost), best.model)


def fit_law(prep: Prepared, idim: InverseDynamics | None = None) -> ArxController:
    """The run's control law from its logged effort (clipped samples left out).

    Of the laws of :func:`law_candidates`, the one kept is the law whose loop, closed around
    the run's own inverse-dynamics plant (mass, damping and a Coulomb force fitted to the
    effort, never to the position, under ``idim``'s delay), reproduces the measured position
    best: the next-effort error cannot choose, because the noise of a logged position that is
    not the controller's own feedback biases exactly the laws that predict the next effort
    best. The choice is among a handful of fits, not a fit of the law to the position, so no
    effect can be absorbed into it.

    Parameters
    ----------
    prep : Prepared
    idim : InverseDynamics, optional
        The run's effort regression (built when not given).

    Raises
    ------
    ValueError
        The run has no effort.
    """
    laws = law_candidates(prep)  # raises without an effort
    assert prep.u is not None
    if len(laws) == 1:
        return laws[0]
    idim = idim if idim is not None else InverseDynamics(prep, prep.u)
    sse, _ = _law_errors(prep, laws, idim)
    if not np.any(np.isfinite(sse)):
        return laws[0]
    return laws[int(np.argmin(sse))]


def law_candidates(prep: Prepared) -> list[ArxController]:
    """The laws a run's effort is fitted to, among which its motion chooses.

    One least-squares law per prefilter of ``settings.law_prefilters``
    (:func:`~fricbench.sysid.diagnose.controllers.fit_arx_controller`). When the effort clips,
    each also with an exact integrator run clamped, as a PID's integral of the position error
    and as the two cascades it can be (a velocity PI integrating the velocity error,
    :meth:`~fricbench.sysid.diagnose.controllers.ArxController.cascade_integral_rates`):
    the unclipped samples cannot tell these apart, the motion after a clip can.

    Raises
    ------
    ValueError
        The run has no effort.
    """
    if prep.u is None:
        raise ValueError("the run has no effort column: no control law to fit")
    nyquist = 0.5 / prep.ts
    # a drive that clips either recurses on its clipped command (velocity form) or holds its
    # integral (positional form, clamped): its unclipped samples cannot tell, its motion can
    forms = (False, True) if prep.saturation is not None else (False,)
    laws = []
    for frac in defaults().law_prefilters:
        for clamped in forms:
            try:
                law = _law_through(prep, None if frac is None else frac * nyquist,
                                   clamped=clamped)
            except (ValueError, np.linalg.LinAlgError):
                continue
            laws.append(law)
            if clamped:
                # a cascade's drive holds the integral of its velocity error (on the second
                # simulator's thermal/21, the PID's clamp left 12.9 um with the true delay,
                # the cascade's 2.8, the velocity form 7.7)
                laws += [replace(law, velocity_ki=ki)
                         for ki in law.cascade_integral_rates(prep.ts)]
    return laws


def _law_errors(prep: Prepared, laws: Sequence[ArxController], idim: InverseDynamics
                ) -> tuple[np.ndarray, np.ndarray]:
    """Squared free-run position errors of each law closed around ``idim``'s plant (mass,
    damping and a Coulomb force fitted to the effort, under its delay, clipping where the
    effort clips): over the whole run, and after its first tenth (inf for a run that fails)."""
    p = idim.fit(("coulomb_friction",), CL.default_plant(1.0, 0.0))
    p[CL.I_DELAY] = idim.delay
    if prep.saturation is not None:
        p[CL.I_IMAX] = prep.saturation.level
    ys, _, status = simulate_models([GreyBox(law, p, effects=("coulomb_friction",))
                                     for law in laws], prep)
    # the late error: the free run starts from a state estimated at the record's edge, and a
    # one-sample shift of the effort can absorb that transient (see fit_law_and_delay)
    k0 = prep.x.shape[0] // 10
    whole, late = np.full(len(laws), np.inf), np.full(len(laws), np.inf)
    for i, (y, s) in enumerate(zip(ys, status, strict=True)):
        if s == 0 and np.all(np.isfinite(y)):
            whole[i] = float(np.sum((prep.x - y) ** 2))
            late[i] = float(np.sum((prep.x[k0:] - y[k0:]) ** 2))
    return whole, late


def fit_law_like(prep: Prepared, like: ArxController) -> ArxController:
    """Another run's control law, fitted through the prefilter ``like`` was chosen with.

    The prefilter is a matter of the log (how much noise its position carries beside the
    controller's own feedback), not of the controller: a validation run of the same axis,
    logged the same way, is fitted through the training run's choice, so that its position
    never chooses its own law (and the injected test pulses of a validation run, which no
    loop without them reproduces, cannot sway the choice).
    """
    if prep.u is None:
        raise ValueError("fit_law_like: the run has no effort column")
    f = like.prefilter_hz
    if f is not None and not f < 0.5 / prep.ts:
        f = None
    law = _law_through(prep, f, clamped=like.clamped)
    if like.velocity_ki > 0.0:
        # the same anti-windup: the cascade whose integral rate is nearest like's
        rates = law.cascade_integral_rates(prep.ts)
        if rates:
            law = replace(law, velocity_ki=min(
                rates, key=lambda ki: abs(math.log(ki / like.velocity_ki))))
    return law


def law_relerr_floor(prep: Prepared) -> float:
    """Smallest next-effort error (%) a linear law reaches on the run (unfiltered fit)."""
    if prep.u is None:
        raise ValueError("law_relerr_floor: the run has no effort column")
    return _law_through(prep, None).relerr_pct


def _law_through(prep: Prepared, prefilter_hz: float | None, *, clamped: bool = False
                 ) -> ArxController:
    """The run's law fitted through ``prefilter_hz`` (None: unfiltered), clipped samples out;
    ``clamped``: with an exact integrator, run in positional form when the drive clips."""
    assert prep.u is not None
    inp = prep.inputs
    exclude = prep.saturation.mask if prep.saturation is not None else None
    law = fit_arx_controller(inp.xr, inp.vr, prep.x, prep.u, prep.ts, prep.folds,
                             exclude=exclude, prefilter_hz=prefilter_hz, integrator=clamped)
    return replace(law, clamped=True) if clamped else law


def fit_law_and_delay(prep: Prepared, idim: InverseDynamics
                      ) -> tuple[ArxController, InverseDynamics]:
    """The run's control law and the drive's command delay, chosen together by the motion.

    The logged effort is the drive's command; its power stage may apply it some samples later
    (:func:`~.equation_error.delay_steps`: up to 3 ms, at the log's rate only). The inverse
    dynamics does not see that shift (its mass and damping bend to it), the free run does: for
    each delay the plant is refitted to the effort shifted by it, and each law of
    :func:`law_candidates` is closed around it with a Coulomb force (:func:`fit_law`'s choice,
    under that delay). The delay whose best law leaves the least position error is kept when it
    is clearly better than none: it leaves less than ``settings.limit_margin`` of the squared
    error, the margin a drive limit found from the position must clear. On the second
    simulator's thermal/21 (a cascade with a 3-sample delay, its current logged) the loop
    without a delay left 14.6 um, with it 7.3 um. The two are chosen together because each bends
    to the other: there, the law chosen without a delay (a cascade's clamp of the wrong integral
    rate) took 2 samples of delay and left 6.3 um, where the true delay with the law it favours
    leaves 2.7. A handful of choices, each refitted to the effort: nothing else the position
    shows can hide in them.

    Returns
    -------
    law : ArxController
    idim : InverseDynamics
        ``idim`` when no delay is kept, else the regression of the shifted effort.
    """
    assert prep.u is not None
    laws = law_candidates(prep)
    delays = delay_steps(prep.inputs.ts) if prep.inputs.n_loop == 1 else (0,)
    cands = [idim] + [InverseDynamics(prep, prep.u, idim.label, delay=d)
                      for d in delays if d > 0]
    best_law, late = [], []
    for cand in cands:
        whole, after = _law_errors(prep, laws, cand)
        i = int(np.argmin(whole)) if np.any(np.isfinite(whole)) else 0
        best_law.append(laws[i])
        # judged after the first tenth of the run: a PD loop started moving, no delay in it,
        # left 0.71 x the error of none over the whole run with a one-sample shift, 1.3 x
        # after its first tenth; a drive's delay acts over the whole run
        late.append(after[i])
    best = int(np.argmin(late))
    # not by the criterion: with the delay counted as one parameter more it gave delays to
    # runs that had none (a twin's mass 12 % off on the tests' paper axis); its late error
    # after the shift is no held-out error, and the plant refitted to the shifted effort
    # bends to it
    if best > 0 and np.isfinite(late[best]) and late[best] < defaults().limit_margin * late[0]:
        return best_law[best], cands[best]
    return best_law[0], idim


def fit_linear_with_effort(prep: Prepared) -> tuple[GreyBox, InverseDynamics, Bounds, float]:
    """Linear grey-box loop from a measured effort: identified controller + IDIM-LS mass.

    Returns
    -------
    model : GreyBox
        ARX controller and the linear plant ``u = M a + B v``.
    idim : InverseDynamics
        The effort regression of the run.
    bounds : Bounds
    law_relerr : float
        Next-effort error (%) of the law, or of the unfiltered least-squares law when that
        is smaller: how far the effort is from any linear law of the logged signals.
    """
    if prep.u is None:
        raise ValueError("fit_linear_with_effort: the run has no effort column")
    idim = InverseDynamics(prep, prep.u)
    ctrl, idim = fit_law_and_delay(prep, idim)
    p = idim.fit((), CL.default_plant(1.0, 0.0))
    p[CL.I_DELAY] = idim.delay
    if prep.saturation is not None:
        p[CL.I_IMAX] = prep.saturation.level
    model = GreyBox(ctrl, p)
    bounds = Bounds(force=force_scale(prep.u, prep.ts), stroke=max(prep.stroke, 1e-9),
                    v_max=max(prep.v_max, 1e-9), duration=prep.duration, ts=prep.ts,
                    noise=prep.noise.rms, rotary=prep.rotary)
    return model, idim, bounds, min(ctrl.relerr_pct, law_relerr_floor(prep))


def friction_aware_fit(linear: GreyBox, prep: Prepared, bounds: Bounds, max_iter: int = 15,
                       *, pid: bool = True,
                       friction_starts: tuple[float, ...] | None = None
                       ) -> PositionFitResult | None:
    """The loop and a Coulomb force fitted together to the position (None: nothing could be
    simulated), from the linear loop and from the best standard loops, each with the Coulomb
    forces ``friction_starts`` (in units of ``bounds.force``; default
    :func:`coulomb_starts`).

    With ``pid`` (the default) the best standard PID position loop is refined too and
    replaces the cascade when the criterion prefers it (:func:`_pid_wins`): a drive whose PID
    has complex P-PI roots or a filtered derivative is no cascade. So are the loops the
    equation error finds with a Coulomb force (:func:`~.equation_error.loop_by_equation_error`),
    one per command delay of :func:`~.equation_error.delay_steps` (up to 3 ms), each refined with
    its delay in the model (a drive's computation and power stage; at the log's rate only): on the
    second simulator's control/10, a PID with a 3-sample delay, the standard loops without a
    delay stopped at 10.3 times the true loop's error, the equation error's start with its
    delay at 1.13 times. Without ``pid`` the loop stays a cascade without delay (the
    ``greybox`` predictor, which models the benchmark's cascade axes).
    """
    cascades = starting_controllers(prep.inputs.loop_ts)
    pids = starting_pid_controllers(prep.inputs.loop_ts) if pid else []
    if friction_starts is None:
        friction_starts = coulomb_starts(bounds)
    if not friction_starts:
        raise ValueError("friction_starts=(): expected at least one Coulomb force")
    loops = [linear] + [linear.copy(controller=c) for c in cascades + pids]
    starts = []
    for level in friction_starts:
        for loop in loops:
            start = loop.copy(effects=("coulomb_friction",))
            start.plant[CL.I_FC] = level * bounds.force
            starts.append(start)
    ys, _, status = simulate_models(starts, prep)
    sse = np.array([np.sum((prep.x - y) ** 2) if s == 0 and np.all(np.isfinite(y)) else np.inf
                    for y, s in zip(ys, status, strict=True)])
    # per friction level: the linear loop, the best standard cascade and the best standard PID
    # loop, refined
    n_c, n_l = len(cascades), len(loops)
    order: list[int] = []
    for j in range(len(friction_starts)):
        o = j * n_l
        order += [o, o + 1 + int(np.argmin(sse[o + 1:o + 1 + n_c]))]
        if pids:
            order.append(o + 1 + n_c + int(np.argmin(sse[o + 1 + n_c:o + n_l])))
    if pid:
        # the loop and friction of the equation error, one per command delay: PID starts near
        # the drive's own, with the delay as a part of the model (at the log's rate only: a
        # faster loop's delay is a fraction of a logged sample)
        delays = delay_steps(prep.inputs.ts) if prep.inputs.n_loop == 1 else (0,)
        for ee in loop_by_equation_error(prep, bounds, n_best=len(delays), delays=delays):
            st = linear.copy(controller=ee.model.controller, effects=("coulomb_friction",))
            st.plant[CL.I_B] = min(float(ee.model.plant[CL.I_B]), bounds.damping_max)
            st.plant[CL.I_FC] = min(max(float(ee.model.plant[CL.I_FC]), 0.02 * bounds.force),
                                    1.5 * bounds.force)
            st.plant[CL.I_DELAY] = ee.delay if prep.inputs.n_loop == 1 else 0
            starts.append(st)
            sse = np.append(sse, 0.0)
            order.append(len(starts) - 1)
    n_grid = len(loops) * len(friction_starts)
    best = None
    best_pid = None
    # independent fits, on two threads at once (the same numbers); with settings.race_share
    # below 1 the starts race (each family's best heat finishes), and an equation error's
    # loop whose heat left a gain on its bound runs no further
    order = [i for i in order if np.isfinite(sse[i])]
    refined = race_fits(
        [(PositionFit(prep, position_params(starts[i], bounds, controller=True)), starts[i])
         for i in order], max_iter, family=_is_pid,
        eligible=lambda j, heat: order[j] < n_grid or _gain_on_bound(heat.model, bounds) is None)
    for i, res in zip(order, refined, strict=True):
        if res is None:
            continue
        if i >= n_grid and _gain_on_bound(res.model, bounds) is not None:
            # an equation error's loop refined to a gain on its bound stands in for another
            # mismatch (a thermal drift, on the second simulator's thermal/2: its feedforwards
            # at 1.5, or its position integral at its least and its derivative filter at its
            # longest, and a force offset named instead of the drift)
            continue
        if _is_pid(res.model):
            if best_pid is None or res.cost < best_pid.cost:
                best_pid = res
        elif best is None or res.cost < best.cost:
            best = res
    # a PID position loop (integral on the position error, filtered derivative) when the
    # criterion prefers it: a cascade reaches only the PIDs with real P-PI gains and no filter
    if best_pid is not None and (best is None or _pid_wins(best_pid, best, prep, bounds)):
        best = best_pid
    return best


def _is_pid(model: GreyBox) -> bool:
    """Whether ``model``'s loop is a PID position loop (else a cascade): the two families of
    loops :func:`friction_aware_fit` compares."""
    return isinstance(model.controller, CascadeController) and model.controller.is_pid


def _pid_wins(pid: PositionFitResult, cascade: PositionFitResult, prep: Prepared,
              bounds: Bounds) -> bool:
    """Whether the PID loop's fit lowers the one criterion against the cascade's.

    ``J = n_eff ln(SSE / n) + penalty k`` on the free-run position error of the training run
    (the Akaike form of the loop structures, ``docs/diagnosis_method.md``), ``k`` the
    parameters each fit moved (the PID's derivative filter is one more), ``n_eff`` that of the
    residual of the fit with more parameters
    (:func:`~fricbench.sysid.diagnose.criterion.comparison_samples`). Both fits minimise the
    same scaled residual, so their costs' ratio is that of their squared errors.
    """
    s = defaults()
    r = prep.x - cascade.y
    if not np.all(np.isfinite(r)):
        return True
    k_pid = len(position_params(pid.model, bounds, controller=True))
    k_cascade = len(position_params(cascade.model, bounds, controller=True))
    n_eff = comparison_samples(r, prep.x - pid.y, k_cascade, k_pid, s.max_lag_share)
    return criterion_change(pid.cost, cascade.cost, k_pid, k_cascade, n_eff, s.penalty) < 0.0


def friction_aware_fit_scaled(linear: GreyBox, prep: Prepared, bounds: Bounds
                              ) -> tuple[PositionFitResult | None, Bounds]:
    """:func:`friction_aware_fit`, and again with the friction levels' bounds
    ``settings.friction_raise`` times higher (:attr:`Bounds.friction_raise`) when its Coulomb force
    ended on its upper bound; the better fit and its bounds.

    A force scale (the linear loop's virtual effort) larger than the reference's largest
    acceleration is checked first: the fit is also run with the acceleration as the force
    scale, and the better fit's scale is the run's (until scale_spread retired, only beyond 100
    times the acceleration: tuned, and the held-out counts held without it). The virtual
    effort is the linear loop's command on the measured position, and a linear loop fitted to
    a run it cannot describe makes it meaningless: on the second simulator's thermal/20 (a
    cascade with a 3-sample command delay, no effort) the linear loop's velocity integral
    summed a feedforward 70 % short over every move, 979 m/s^2 against a reference
    accelerating at 0.37 and a true friction of 0.66. The friction's starts and its
    optimiser's scale being multiples of the force scale, the fit settled on a friction of 59
    and a loop 7 times too fast (26 um left); at the acceleration's scale it reaches the true
    loop within 5 % and a friction of 0.70 (3.0 um).

    The run's force scale (the reference's largest acceleration, or the linear loop's virtual
    effort) is the inertial force of the motion, and every force's bounds and starts are
    multiples of it. A slow axis can be held by a friction many times that: on the second
    simulator's posdep/28 the Coulomb force per unit mass was 20 times the scale, the fit
    stopped on its bound of 2, the loop's gains took up the rest and the friction varying along
    the stroke was never found. A level pressed against a bound that is no physical limit is
    refitted beyond it (the issue's rule for a parameter on its bound), from the same starts;
    the raised bounds then hold for the whole search, whose later fits would press against the
    same bound. The starts of the other forces stay multiples of the force scale (raising the
    scale itself moved them too, and a Stribeck friction present was lost from them).
    """
    fit = friction_aware_fit(linear, prep, bounds)
    a_ref = reference_acceleration(prep)
    if 0.0 < a_ref < bounds.force:
        motion = replace(bounds, force=a_ref)
        other = friction_aware_fit(linear, prep, motion)
        if other is not None and (fit is None or other.cost < fit.cost):
            fit, bounds = other, motion
    if fit is None or "coulomb_friction" not in fit.model.effects:
        return fit, bounds
    fc = float(fit.model.plant[CL.I_FC])
    if get_effect("coulomb_friction").bounds(CL.I_FC, fc, bounds).bound_hit(fc) != "upper":
        return fit, bounds
    raised = replace(bounds, friction_raise=bounds.friction_raise * defaults().friction_raise)
    refit = friction_aware_fit(linear, prep, raised)
    if refit is not None and refit.cost < fit.cost:
        return refit, raised
    return fit, bounds


def _gain_on_bound(model: GreyBox, bounds: Bounds) -> str | None:
    """The loop gain of ``model`` that ended on a bound of :func:`~.models.position_params`
    (None: none did). A lower bound of 0 (no feedforward, no derivative filter) is a value a
    loop has, not a bound it was pushed to."""
    tol = defaults().bound_tolerance
    for p in position_params(model, bounds, controller=True, damping=False, effects=()):
        if not isinstance(p.target, str):
            continue
        v = p.get(model)
        if v >= p.hi * (1.0 - tol) or (p.lo > 0.0 and v <= p.lo * (1.0 + tol)):
            return p.target
    return None


def friction_aware_loop(linear: GreyBox, prep: Prepared, bounds: Bounds, max_iter: int = 15,
                        *, pid: bool = True, fit: PositionFitResult | None = None,
                        friction_starts: tuple[float, ...] | None = None) -> GreyBox:
    """The loop gains identified together with a Coulomb friction force.

    Without an effort, a linear fit hardly sees the feedback gains: with feedforward the
    reference is tracked almost whatever they are, and what the gains do show is the response
    to disturbances, which a linear model does not have. Friction is the disturbance every
    axis has, so the gains are identified with a Coulomb force in the model
    (:func:`friction_aware_fit` from ``friction_starts``, or its result ``fit``). The
    returned model is linear again -
    the loop of the joint fit with the linear plant refitted - and is the base the candidate
    effects are judged against; whether friction itself belongs in the model is then judged
    like any other effect.
    """
    best = fit if fit is not None else friction_aware_fit(
        linear, prep, bounds, max_iter, pid=pid, friction_starts=friction_starts)
    if best is None:
        return linear
    loop = best.model.controller
    base = linear.copy(controller=loop)
    res = PositionFit(prep, position_params(base, bounds, controller=False)).run(base, 8)
    return res.model


def coulomb_starts(bounds: Bounds) -> tuple[float, ...]:
    """Coulomb forces the friction-aware fit starts from, in units of ``bounds.force``.

    The drive limit's grid of Coulomb forces (``settings.limit_friction_grid``, factors of 2)
    inside the Coulomb level's range before any raise of it (below its bound: 0.25, 0.5 and
    1): one grid of Coulomb starts for the loop's friction and the drive limit. The joint fit
    of a loop and its friction has several minima; the grid spans them as it spans the
    limit's split. Those starts were a tuned field, ``friction_starts`` (0.3 and 1), until
    the held-out sets judged the grid (docs/diagnosis_method.md).

    Raises
    ------
    ValueError
        When no entry of the grid lies below the bound.
    """
    unraised = replace(bounds, friction_raise=1.0)
    top = get_effect("coulomb_friction").bounds(CL.I_FC, 0.0, unraised).hi / bounds.force
    grid = defaults().limit_friction_grid
    starts = tuple(g for g in grid if g < top)
    if not starts:
        # a valid grid of the settings can still leave the fit no start: name the field
        raise ValueError(f"limit_friction_grid={grid!r}: expected at least one entry below "
                         f"{top:g}, the Coulomb level's bound in units of the run's force scale "
                         "(the friction-aware fit starts from those entries)")
    return starts
