"""The diagnosis workflow: linear baseline -> residual -> missing effect -> refit -> errors.

:func:`diagnose` is the library entry point behind ``fricbench diagnose``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import cast

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.baselines import (
    DriveLimit,
    LinearTF,
    drive_limits,
    fit_law_like,
    fit_linear_cascade,
    fit_linear_tf,
    fit_linear_with_effort,
    friction_aware_fit_scaled,
    friction_aware_loop,
)
from fricbench.sysid.diagnose.controllers import ArxController, CascadeController
from fricbench.sysid.diagnose.coverage import Coverage, coverage
from fricbench.sysid.diagnose.criterion import (
    comparison_samples,
    criterion_change,
    profile_statistic,
)
from fricbench.sysid.diagnose.effects import describe_parameters, get_effect
from fricbench.sysid.diagnose.leastsq import sumsq
from fricbench.sysid.diagnose.models import (
    GreyBox,
    InverseDynamics,
    PositionFit,
    position_params,
    run_concurrently,
    simulate_position,
)
from fricbench.sysid.diagnose.parameters import Bounds
from fricbench.sysid.diagnose.prepared import Prepared, prepare, substeps
from fricbench.sysid.diagnose.search import SearchResult, effects_tried, forward_selection
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS, DiagnoseSettings, defaults
from fricbench.sysid.diagnose.signals import (
    NoiseFloor,
    SensorLine,
    disturbance_warning,
    mains_visible,
    rest_segments,
    sensor_lines,
)
from fricbench.sysid.diagnose.uncertainty import ModelUncertainty, model_uncertainty
from fricbench.sysid.diagnose.verdict import Verdict, judge
from fricbench.sysid.io import RunData

__all__ = ["diagnose", "DiagnosisResult", "RunEvaluation", "DiagnosisError"]


@dataclass
class RunEvaluation:
    """Errors of the linear and the final model on one run.

    Attributes
    ----------
    y_before, y_after : ndarray
        Free-run positions of the linear and final model, m.
    effort_before, effort_after : float or None
        Relative effort errors of the inverse dynamics over every sample, %.
    effort_sliding_before, effort_sliding_after : float or None
        The same over the samples where the axis slides (speed above 5 % of its largest), %:
        at rest the effort is whatever the controller's integrator holds against stiction,
        which no friction model predicts; ``None`` with fewer than 20 such samples.
    injected_share : float or None
        Rms share of the effort the controller law does not explain (runs with effort).
    used_injected : bool
        Whether that remainder was fed to the simulations as an injected effort.
    """

    prep: Prepared
    y_before: np.ndarray = field(repr=False)
    y_after: np.ndarray = field(repr=False)
    effort_before: float | None
    effort_after: float | None
    injected_share: float | None = None
    used_injected: bool = False
    effort_sliding_before: float | None = None
    effort_sliding_after: float | None = None

    def position(self) -> dict[str, float]:
        """The issue's position metrics, m."""
        x = self.prep.x
        eb, ea = x - self.y_before, x - self.y_after
        return {"rms_before": _rms(eb), "rms_after": _rms(ea),
                "max_before": float(np.max(np.abs(eb))), "max_after": float(np.max(np.abs(ea)))}

    def effort(self) -> dict[str, float] | None:
        """The issue's effort metrics, %."""
        if self.effort_before is None or self.effort_after is None:
            return None
        out = {"relerr_before_pct": self.effort_before, "relerr_after_pct": self.effort_after}
        if self.effort_sliding_before is not None and self.effort_sliding_after is not None:
            out["relerr_sliding_before_pct"] = self.effort_sliding_before
            out["relerr_sliding_after_pct"] = self.effort_sliding_after
        return out


@dataclass
class DiagnosisResult:
    """Everything :func:`diagnose` found.

    Attributes
    ----------
    run : RunData
    prep : Prepared
    mode : str
        ``"effort"`` (inverse dynamics available) or ``"position"`` (position only).
    force_unit : str
        Unit of the force parameters.
    linear : GreyBox
        The linear model.
    search : SearchResult
    train : RunEvaluation
    validation : RunEvaluation or None
    linear_tf : LinearTF or None
        The black-box transfer function, when requested.
    elapsed_s : float
        Wall time of the whole diagnosis, s.
    validation_coverage : Coverage or None
        How much of the validation run lies beyond the speeds and the stroke the training
        run covered (its warnings are among the diagnosis's).
    """

    run: RunData
    prep: Prepared
    mode: str
    force_unit: str
    linear: GreyBox
    search: SearchResult
    train: RunEvaluation
    validation: RunEvaluation | None
    validation_run: RunData | None
    linear_tf: LinearTF | None
    elapsed_s: float
    notes: list[str] = field(default_factory=list)
    laws: dict[str, str] = field(default_factory=dict)
    diagnosis_warnings: list[str] = field(default_factory=list)
    mode_comparison: dict[str, object] | None = None
    not_detected: list[dict[str, object]] = field(default_factory=list)
    profile_detected: dict[str, dict[str, float]] = field(default_factory=dict)
    """Effects of the final model within ``detection_sd`` of zero by the Jacobian that the
    profile form of the test detects: ``size_over_sd``, ``profile_statistic``, ``sse_ratio``."""
    validation_coverage: Coverage | None = None
    uncertainty: ModelUncertainty | None = None
    loop_decisions: list[dict[str, object]] = field(default_factory=list)
    """Loop structures tried beside the chosen one (a faster loop, a drive limit) and the
    criterion's decision on each."""
    sensor_lines: list[SensorLine] = field(default_factory=list)
    """Periodic components of the measurement that are no motion (mains hum), found in the
    rests of the reference and in the final residual (:func:`_sensor_disturbance`)."""
    floor: float | None = None
    """The floor of a free-run prediction the verdict uses when there are sensor lines: the
    search's with the lines' power added; None: the search's."""

    @property
    def noise(self) -> NoiseFloor:
        """The position's noise floor with every sensor line found (rests and residual) in
        it; the search's ``prep.noise`` is the sensor's own."""
        return self.prep.noise.with_lines(self.sensor_lines) if self.sensor_lines else \
            self.prep.noise

    @property
    def prediction_floor(self) -> float:
        """The floor of a free-run prediction the verdict compares the residual with, SI."""
        return self.search.floor if self.floor is None else self.floor

    @property
    def warnings(self) -> list[str]:
        """The runs' reading warnings, then the diagnosis's, in order."""
        out = list(self.run.warnings)
        if self.validation_run is not None:
            out += list(self.validation_run.warnings)
        return out + list(self.diagnosis_warnings)

    def verdict(self) -> Verdict:
        """The verdict (:mod:`fricbench.sysid.diagnose.verdict`)."""
        pos = self.train.position()
        if self.validation is not None:
            vpos = self.validation.position()
            held, name = (vpos["rms_before"], vpos["rms_after"]), "validation"
        else:
            held, name = (pos["rms_before"], pos["rms_after"]), "training (free run)"
        unit = self.run.logged_unit
        return judge(self.effects, pos["rms_after"], max(self.prediction_floor, 1e-300),
                     self.prep.x - self.train.y_after, self.prep.x, self.prep.inputs.vr,
                     self.prep.ts, heldout=held, heldout_name=name,
                     length=lambda v: f"{v * unit.per_si:.4g} {unit.display}",
                     lines=[ln.frequency_hz for ln in self.sensor_lines])

    @property
    def effects(self) -> list[str]:
        """Effects added, in order."""
        return [s.effect for s in self.search.steps[1:] if s.effect is not None]

    @property
    def final(self) -> GreyBox:
        """The final model."""
        return self.search.final.model

    def to_dict(self) -> dict[str, object]:
        """JSON-ready report: effects, position, effort, validation (details beside them).

        Figures are in SI. For a rotary axis (positions in rad, ``run.units["position"]``)
        the keys say so: ``position_rms_rad``, ``period_rad`` and so on instead of ``_m``;
        ``data.position_unit`` records the unit the log was in.
        """
        fu = self.force_unit
        steps = []
        for i, st in enumerate(self.search.steps[1:], start=1):
            assert st.effect is not None
            metrics: dict[str, object] = {"position_rms_m": st.position_rms,
                                          "position_max_m": st.position_max}
            if st.effort_relerr_pct is not None:
                metrics["effort_relerr_pct"] = st.effort_relerr_pct
            if st.heldout_ratio is not None:
                metrics["heldout_error_ratio"] = st.heldout_ratio
                metrics["heldout_gain_pct"] = 100.0 * (1.0 - st.heldout_ratio)
            steps.append({
                "step": i,
                "effect": st.effect,
                "parameters": describe_parameters(st.effect, st.model.plant, fu),
                "metrics": metrics,
                "model": _model_dict(st.model, fu),
                "candidates": [c.to_dict() for c in st.candidates],
            })
        verdict = self.verdict()
        out: dict[str, object] = {
            "verdict": verdict.verdict,
            "verdict_detail": verdict.to_dict(),
            "effects": self.effects,
            "position": self.train.position(),
        }
        eff = self.train.effort()
        if eff is not None:
            out["effort"] = eff
        out["steps"] = steps
        # the final model's values (each step's are those it was added with, before the
        # later steps' refits): what the twin holds
        final = self.search.final.model
        out["parameters"] = {e: describe_parameters(e, final.plant, fu) for e in final.effects}
        if self.uncertainty is not None and self.uncertainty.sd:
            unc = self.uncertainty.to_dict()
            out["parameter_sd"] = unc.pop("parameter_sd")
            out["uncertainty"] = dict(unc, detection_sd=DEFAULT_SETTINGS.detection_sd,
                                      note="standard deviations from the Jacobian of the "
                                           "free-run error at the final model, every free "
                                           "parameter (loop, damping, effects) in it")
        out["not_detected"] = self.not_detected
        out["profile_detected"] = self.profile_detected
        if self.validation is not None and self.validation_run is not None:
            val: dict[str, object] = {"source": self.validation_run.source,
                                      "position": self.validation.position()}
            veff = self.validation.effort()
            if veff is not None:
                val["effort"] = veff
            if self.validation.injected_share is not None:
                val["injected_effort_share_pct"] = 100.0 * self.validation.injected_share
                val["injected_effort_used"] = self.validation.used_injected
            if self.validation_coverage is not None:
                val["coverage"] = self.validation_coverage.to_dict()
            out["validation"] = val
        first = self.search.steps[0]
        rejected = self.search.final.rejected
        pos = self.train.position()
        out["linear_model"] = {"model": _model_dict(self.linear, fu),
                               "position_rms_m": pos["rms_before"],
                               "position_max_m": pos["max_before"]}
        if first.effort_relerr_pct is not None:
            out["linear_model"]["effort_relerr_pct"] = first.effort_relerr_pct  # type: ignore
        if first.model is not self.linear:
            out["search_base_model"] = {
                "note": "the linear plant with the loop gains identified together with a "
                        "Coulomb force: the base the candidate effects were judged against",
                "model": _model_dict(first.model, fu), "position_rms_m": first.position_rms}
        if self.linear_tf is not None and self.linear_tf.y is not None:
            e = self.prep.x - self.linear_tf.y
            out["linear_tf"] = {"orders": list(self.linear_tf.order), "position_rms_m": _rms(e),
                                "position_max_m": float(np.max(np.abs(e))),
                                "tf": str(self.linear_tf.tf).strip()}
        out["controller_laws"] = dict(self.laws)
        if self.mode_comparison is not None:
            out["mode_comparison"] = self.mode_comparison
        out["loop_structure"] = list(self.loop_decisions)
        out["stop_reason"] = self.search.stop_reason
        out["rejected_at_last_step"] = [c.to_dict() for c in rejected]
        out["noise_floor"] = dict(self.noise.to_dict(), prediction_floor_m=self.prediction_floor)
        logged = self.run.logged_unit
        out["sensor_disturbance"] = [ln.to_dict(logged.to_si, logged.name)
                                     for ln in self.sensor_lines]
        out["data"] = {"source": self.run.source, "samples": self.run.n_samples,
                       "ts_s": self.run.ts, "duration_s": self.run.duration,
                       "reversals": self.run.n_reversals, "columns": self.run.columns,
                       "mode": self.mode, "force_unit": fu,
                       "derivative_filter_hz": self.prep.cutoff_hz,
                       "decimation": self.prep.decim,
                       "filter_chosen_by": self.prep.filter_source,
                       # the plant's integration step of every free run reported
                       "integration_step_s": self.prep.inputs.loop_ts / self.prep.n_sub}
        if self.prep.saturation is not None:
            out["data"]["effort_saturation"] = self.prep.saturation.to_dict()  # type: ignore
        if self.train.injected_share is not None:
            out["data"]["injected_effort_share_pct"] = 100.0 * self.train.injected_share  # type: ignore
        out["warnings"] = self.warnings
        out["notes"] = list(self.notes)
        out["elapsed_s"] = self.elapsed_s
        si = self.run.units.get("position", "m")
        out["data"]["position_unit"] = self.run.units.get("position_logged", si)  # type: ignore
        out["data"]["position_unit_si"] = si  # type: ignore
        if si == "rad":
            # a rotary axis: the same SI figures, keyed in rad (period_rad, position_rms_rad)
            renamed = cast(dict, _rotary_keys(out))
            data = renamed["data"]
            if data["force_unit"] == "m_s2":
                data["force_unit"] = "rad_s2"
            return renamed
        return out


class DiagnosisError(ValueError):
    """No valid model of the run exists (every candidate loop diverges, say)."""


def _runs_away(prep: Prepared, y: np.ndarray) -> bool:
    """Whether a free run left the data: its rms error exceeds ``settings.unstable_factor``
    strokes."""
    return _rms(prep.x - y) > defaults().unstable_factor * max(prep.stroke, prep.noise.rms)


def _law_unusable(prep: Prepared, y_lin: np.ndarray) -> str | None:
    """Why the control law identified from the effort cannot drive the simulations, or None.

    Only a loop that cannot be simulated (its free run diverges or leaves the data) is
    refused here. A law that explains the effort poorly still drives the effort's search,
    and the criterion then chooses between that diagnosis and the position's
    (:func:`_better_of`): a law leaving more than 25 % of the effort unexplained was refused
    outright (``law_max_relerr_pct``, tuned on EMPS and the second simulator), retired when
    both held-out sets gave every row as with it.
    """
    e = prep.x - y_lin
    if not np.all(np.isfinite(e)):
        return ("the control law identified from the effort closes an unstable loop with "
                "the linear plant (its free run diverges)")
    if _runs_away(prep, y_lin):
        return ("the control law identified from the effort, with the linear plant, runs "
                "away from the data (free-run error larger than the stroke)")
    return None


def _rotary_keys(obj: object) -> object:
    """``obj`` with the length unit ``m`` in its keys (``_m`` tokens) read as ``rad``."""
    if isinstance(obj, dict):
        return {("_".join("rad" if tok == "m" else tok for tok in k.split("_"))
                 if isinstance(k, str) else k): _rotary_keys(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_rotary_keys(v) for v in obj]
    return obj


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e**2))) if np.all(np.isfinite(e)) else float("inf")


def _model_dict(model: GreyBox, force_unit: str) -> dict[str, object]:
    p = model.plant
    if force_unit == "m_s2":
        plant = {"mass": "normalised to 1", "damping_1_s": float(p[CL.I_B])}
    else:
        plant = {f"mass_{force_unit}_s2_m": float(p[CL.I_M]),
                 f"damping_{force_unit}_s_m": float(p[CL.I_B])}
    if p[CL.I_DELAY] > 0:
        plant["command_delay_loop_periods"] = int(p[CL.I_DELAY])
    return {"controller": model.controller.to_dict(), "plant": plant,
            "effects": {e: describe_parameters(e, p, force_unit) for e in model.effects}}


def _sensor_disturbance(prep: Prepared, search_floor: float, y_after: np.ndarray,
                        settings: DiagnoseSettings) -> tuple[list[SensorLine], float | None]:
    """The sensor's periodic disturbances and the floor of a free-run prediction with them.

    Lines of the mains are sought in the rests of the reference (the axis still, its transient
    left out: :func:`~fricbench.sysid.diagnose.signals.rest_segments`) and in the final
    residual; a line found in both keeps the rests' amplitude (the cleanest view of the
    sensor). One grid feeds a site: when lines of both fundamentals are found, those of the
    one whose lines carry less power are dropped.

    The floor: the search's (the sensor's noise and quantisation fed through the loop) with the
    lines' power added, ``hypot(search_floor, rms of the lines)``: the model's free run has no
    hum, so its residual carries the measured lines whole. None without lines. The search
    itself keeps the sensor's floor: its decisions (the loop, the effects) are those of a run
    without the lines.
    """
    st, sensor = settings, prep.noise.sensor_rms
    xr = prep.inputs.xr
    found = sensor_lines(prep.x - xr, prep.ts, rest_segments(xr, prep.ts, st), "rests", st,
                         floor=sensor)
    r = prep.x - y_after
    residual = (sensor_lines(r, prep.ts, [(0, prep.n)], "residual", st, floor=sensor)
                if np.all(np.isfinite(r)) else [])
    merged = {(ln.mains_hz, ln.harmonic): ln for ln in found}
    for ln in residual:
        key = (ln.mains_hz, ln.harmonic)
        merged[key] = (dataclasses.replace(merged[key], where="rests and residual")
                       if key in merged else ln)
    if not merged:
        return [], None
    power: dict[float, float] = {}
    for ln in merged.values():
        power[ln.mains_hz] = power.get(ln.mains_hz, 0.0) + ln.variance
    grid = max(power, key=lambda f: power[f])
    lines = sorted((ln for ln in merged.values() if ln.mains_hz == grid),
                   key=lambda ln: ln.frequency_hz)
    disturbance = math.sqrt(sum(ln.variance for ln in lines))
    return lines, math.hypot(search_floor, disturbance)


def _injected(model: GreyBox, prep: Prepared) -> tuple[np.ndarray | None, float | None, bool]:
    """The effort ``model``'s identified law leaves unexplained on ``prep`` (test pulses, a
    feedback the log does not hold), its rms share of the effort, and whether it is fed to
    the free runs as an injected input: when ``model``'s free run with it is closer to the
    measured position than without it (the two runs have the same parameters, so the
    criterion is their squared errors). None, None, False without an effort or a law."""
    ctrl = model.controller
    if prep.u is None or not isinstance(ctrl, ArxController):
        return None, None, False
    inp = prep.inputs
    w = prep.u - ctrl.predict(inp.xr, inp.vr, prep.x, prep.u, prep.ts)
    # the first and last samples miss the law's history (the reference is extended at
    # constant velocity): a mismatch there is the start, not an injected input
    n_edge = defaults().law_edge
    edge = slice(n_edge, -n_edge) if w.shape[0] > 4 * n_edge else slice(None)
    share = float(np.sqrt(np.mean(w[edge]**2)) / max(np.sqrt(np.mean(prep.u[edge]**2)), 1e-300))
    sse = [sumsq(prep.x - simulate_position(model, prep, v)[0]) for v in (w, None)]
    use = bool(np.isfinite(sse[0]) and not sse[1] <= sse[0])
    return (w if use else None), share, use


def _on_run(model: GreyBox, prep: Prepared, law: ArxController | None) -> GreyBox:
    """``model``'s plant in the loop of another run: that run's own law and actuator limit."""
    if law is None:
        return model
    p = model.plant.copy()
    p[CL.I_IMAX] = prep.saturation.level if prep.saturation is not None else np.inf
    return model.copy(controller=law, plant=p)


def _evaluate(linear: GreyBox, final: GreyBox, prep: Prepared,
              law: ArxController | None = None) -> RunEvaluation:
    linear, final = _on_run(linear, prep, law), _on_run(final, prep, law)
    w, share, used = _injected(final, prep)
    y_before, _ = simulate_position(linear, prep, w)
    y_after, _ = simulate_position(final, prep, w)
    eb = ea = sb = sa = None
    if prep.u is not None and isinstance(final.controller, ArxController):
        idim = InverseDynamics(prep, prep.u, delay=int(final.plant[CL.I_DELAY]))
        eb, ea = idim.relerr(linear.plant), idim.relerr(final.plant)
        speed = np.abs(idim.v_dec)
        sliding = np.flatnonzero(speed > defaults().rest_speed_share
                                 * float(np.max(speed, initial=0.0)))
        if sliding.size >= defaults().min_sliding_samples:
            sb, sa = idim.relerr(linear.plant, sliding), idim.relerr(final.plant, sliding)
    return RunEvaluation(prep, y_before, y_after, eb, ea, share, used, sb, sa)


@dataclass
class _ModeFit:
    """One diagnosis of the training run, with the effort's law or on the position alone."""

    mode: str
    force_unit: str
    prep: Prepared
    linear: GreyBox
    search: SearchResult
    train: RunEvaluation
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    laws: dict[str, str] = field(default_factory=dict)
    comparison: dict[str, object] | None = None
    bounds: Bounds | None = None
    loop_decisions: list[dict[str, object]] = field(default_factory=list)
    """The loop structures tried beside this one and how the criterion judged them
    (:func:`_loop_choice`)."""

    @property
    def finite(self) -> bool:
        """Whether both free runs of the training run stay finite."""
        return bool(np.all(np.isfinite(self.train.y_after))
                    and np.all(np.isfinite(self.train.y_before)))

    @property
    def sse(self) -> float:
        """Squared free-run position error of the final model (inf after a divergence)."""
        e = self.prep.x - self.train.y_after
        return float(np.sum(e**2)) if np.all(np.isfinite(e)) else float("inf")


def _clamped_words(ctrl: ArxController | CascadeController) -> str:
    """What the report adds to a law that holds its integral while the drive clips."""
    if isinstance(ctrl, ArxController) and ctrl.clamped:
        held = ("the integral of a velocity PI (a cascade's: integral rate "
                f"{ctrl.velocity_ki:.4g} 1/s)" if ctrl.velocity_ki > 0.0
                else "its integral of the position error (a PID's)")
        return (f"; run with {held} held while the drive clips (clamping anti-windup), "
                "which reproduced the motion better than a law recursing on its clipped "
                "command")
    return ""


def _fit_effort(run: RunData, prep: Prepared, linear: GreyBox, idim: InverseDynamics,
                bounds: Bounds, ctrl_err: float, y_lin: np.ndarray,
                injected: tuple[np.ndarray | None, float | None, bool], force_unit: str,
                settings: DiagnoseSettings, log: Callable[[str], None],
                t0: float) -> _ModeFit:
    """The search with the law identified from the effort and the inverse dynamics."""
    w, share, used = injected
    notes = [f"controller law identified from the effort with {ctrl_err:.2f} % relative error"]
    laws = {"train": f"identified on the training run ({ctrl_err:.2f} % relative error)"
                     f"{_clamped_words(linear.controller)}"}
    delay = int(linear.plant[CL.I_DELAY])
    if delay > 0:
        laws["train"] += (f"; the drive applies its command {delay} loop period"
                          f"{'s' if delay > 1 else ''} ({1e3 * delay * prep.inputs.loop_ts:.3g}"
                          " ms) after it is logged, found from the motion")
    if share is not None:
        # said either way: a user reading injected_effort_share_pct should know why a
        # remainder of any size was fed or left out
        fed = ("it is fed to the simulations as an injected input" if used else
               "it is not fed to the simulations: the free run with it is no closer to the "
               "measured position (noise on the logged effort, or what the law misses)")
        notes.append(f"{100 * share:.1f} % (rms) of the effort is not explained by the "
                     f"controller law; {fed}")
    log(f"  linear position rms {_rms(prep.x - y_lin) * run.logged_unit.per_si:.4g} "
        f"{run.logged_unit.display} ({time.perf_counter() - t0:.1f} s)")
    search = forward_selection(linear, y_lin, prep, bounds, idim=idim, w=w, jac=None,
                               settings=settings, alt_loops=(), log=log)
    log(f"stop: {search.stop_reason}")
    train = _evaluate(linear, search.final.model, prep)
    return _ModeFit("effort", force_unit, prep, linear, search, train, notes, [], laws,
                    bounds=bounds)


@dataclass
class _LoopBase:
    """The linear loop of a position-mode diagnosis and what the search starts from."""

    prep: Prepared
    linear: GreyBox
    y_lin: np.ndarray
    bounds: Bounds
    jac: np.ndarray | None
    alt: tuple
    limit: DriveLimit | None
    cost: float
    with_friction: GreyBox | None = None
    tentative_limit: DriveLimit | None = None
    """A drive limit the loop with friction alone could not confirm
    (:func:`~fricbench.sysid.diagnose.baselines.drive_limits`); see :func:`_with_limit`."""
    friction_sse: float = math.inf
    """Squared error of the loop fitted with friction (without a limit)."""


def _refit_linear(linear: GreyBox, prep: Prepared, bounds: Bounds, column: int, value: float
                  ) -> tuple[GreyBox, np.ndarray] | None:
    """The linear loop refitted to the position (its gains free) with plant entry ``column``
    set to ``value`` (a drive's limit or command delay, found after the gains were fitted),
    and its free run; None when that loop diverges or runs away from the position."""
    start = linear.copy(plant=linear.plant.copy())
    start.plant[column] = value
    refit = PositionFit(prep, position_params(start, bounds, controller=True)).run(
        start, max_iter=15)
    if not np.all(np.isfinite(refit.y)) or _runs_away(prep, refit.y):
        return None
    return refit.model, refit.y


def _loop_base(prep: Prepared, n_reversals: int) -> _LoopBase:
    """The linear loop fitted to the position, the loop fitted with friction (and the
    drive's limit when one shows) that the search also tries, and the squared error of the
    best of those fits (to compare loop rates)."""
    try:
        linear, y_lin, bounds, jac = fit_linear_cascade(prep)
    except ValueError as exc:
        raise DiagnosisError(f"no valid linear model of this run: {exc}") from exc
    if not np.all(np.isfinite(y_lin)) or _runs_away(prep, y_lin):
        raise DiagnosisError("no valid linear model of this run: every linear loop fitted "
                             "to the position diverges or misses it by more than the "
                             "stroke")
    cost = float(np.sum((prep.x - y_lin) ** 2))
    alt: tuple = ()
    limit = None
    fit = None
    near = None
    fit_sse = math.inf
    if n_reversals > 0:
        fit, bounds = friction_aware_fit_scaled(linear, prep, bounds)
        delay = int(fit.model.plant[CL.I_DELAY]) if fit is not None else 0
        if delay > 0:
            # the loop fitted with friction holds a command delay (from the equation error's
            # starts): it is the drive's, as a limit is, and every model of the run gets it,
            # the linear one refitted with it
            refit = _refit_linear(linear, prep, bounds, CL.I_DELAY, delay)
            if refit is not None:
                linear, y_lin = refit
                cost = min(cost, float(np.sum((prep.x - y_lin) ** 2)))
            else:
                fit = None  # a delay the linear loop cannot hold: the search runs without
        limit, near = drive_limits(fit, prep, bounds) if fit is not None else (None, None)
        fit_sse = (float(np.sum((prep.x - fit.y) ** 2)) if fit is not None
                   and np.all(np.isfinite(fit.y)) else math.inf)
        cost = min(cost, fit_sse)
        if limit is not None:
            limited = _limited(prep, linear, bounds, limit, cost, fit_sse)
            if limited is None:
                raise DiagnosisError("no valid linear model of this run: the linear loop "
                                     "with the identified drive limit diverges")
            linear, y_lin, cost = limited
        # the alternative loop: the one fitted with the limit and friction together when the
        # drive clips, else the loop fitted with friction (with the linear plant refitted)
        loop = (limit.model if limit is not None
                else friction_aware_loop(linear, prep, bounds, fit=fit))
        alt = (loop.controller,)
    return _LoopBase(prep, linear, y_lin, bounds, jac, alt, limit, cost,
                     fit.model if fit is not None else None, near, fit_sse)


def _with_limit(base: _LoopBase) -> _LoopBase | None:
    """``base`` with its tentative drive limit (its linear loop refitted under it), for the
    search to try too; None without one or when that loop diverges. Built only when the
    search needs it (a refit of the linear loop)."""
    near = base.tentative_limit
    if near is None:
        return None
    limited = _limited(base.prep, base.linear, base.bounds, near, base.cost, base.friction_sse)
    if limited is None:
        return None
    return _LoopBase(base.prep, limited[0], limited[1], base.bounds, base.jac,
                     (near.model.controller,), near, limited[2], base.with_friction)


def _limited(prep: Prepared, linear: GreyBox, bounds: Bounds, limit: DriveLimit, cost: float,
             fit_sse: float) -> tuple[GreyBox, np.ndarray, float] | None:
    """The linear loop refitted under a drive limit (every model of the run then clips there,
    the linear one included, as with a clipping effort: its gains were fitted without one),
    its free run and the base's cost with the limit; None when that loop diverges."""
    refit = _refit_linear(linear, prep, bounds, CL.I_IMAX, limit.level)
    if refit is None:
        return None
    return refit[0], refit[1], min(cost, limit.sse_ratio * fit_sse)


def _fit_position(run: RunData, prep: Prepared, settings: DiagnoseSettings,
                  log: Callable[[str], None], t0: float,
                  effort_check: InverseDynamics | None = None) -> _ModeFit:
    """The search on the position alone: a loop fitted to the position, forces per unit mass
    (``effort_check``: the regression of an effort the run logs but whose law was set aside,
    which a force effect must not contradict)."""
    log("linear model: cascade controller on a unit mass, output-error fit")
    slow = _loop_base(prep, run.n_reversals)
    n_fast = int(round(prep.ts / settings.loop_ts))
    fast = None
    if n_fast >= 2:
        # a log slower than a drive's loop: the loop is also fitted at settings.loop_ts, kept when
        # its fit (with friction and the drive's limit) is clearly closer to the data
        try:
            fast = _loop_base(prep.with_loop(n_fast), run.n_reversals)
        except DiagnosisError:
            fast = None
    fast_note = None
    best = _search_position(slow, run, settings, log, t0, effort_check)
    best_base = slow
    decisions: list[dict[str, object]] = []
    # a loop structure is a candidate of the search as an effect is: the loop at the log's
    # rate and the faster loop of a drive, with and without a drive limit, each searched
    # for its effects and judged by the one criterion on held-out error (_loop_choice). The
    # faster loop is searched when its fit with friction is closer to the data than the
    # slow one's (in-sample: the cheap filter of a costly candidate)
    if fast is not None and fast.cost < slow.cost and best.sse > 0.0:
        log(f"  the loop at {n_fast} periods per logged sample fits the run with friction "
            f"better ({100 * fast.cost / slow.cost:.2g} % of the squared error): the search "
            "also runs with it")
        note = _fast_loop_note(prep, n_fast, fast.cost, slow.cost, "with friction")
        second = _search_position(fast, run, settings, log, t0, effort_check, fast_note=note)
        decision = _loop_choice(second, best, 0, f"the loop at {n_fast} periods per logged "
                                "sample, against the log's rate", settings, log)
        decisions.append(decision)
        if decision["accepted"]:
            best, best_base, fast_note = second, fast, note
    tentative = _with_limit(best_base) if best.sse > 0.0 else None
    if tentative is not None and tentative.limit is not None:
        near = tentative.limit
        log(f"  a drive limit of {near.level:.4g} m/s^2 per unit mass fits about as well "
            f"({100 * near.sse_ratio:.2g} % of the squared error with friction alone): the "
            "search also runs with it")
        limited = _search_position(tentative, run, settings, log, t0, effort_check,
                                   fast_note=fast_note)
        # the limit is one fitted parameter more
        decision = _loop_choice(limited, best, 1, "a drive limit, against none", settings, log)
        decisions.append(decision)
        if decision["accepted"]:
            limited.notes.append(
                "the drive's limit is kept although the loop with friction alone fitted about "
                "as well without it: with the effects found it lowers the held-out criterion "
                f"by {-cast(float, decision['criterion_change']):.3g}")
            best = limited
    best.loop_decisions = decisions
    return best


def _loop_choice(new: _ModeFit, old: _ModeFit, extra_params: int, what: str,
                 settings: DiagnoseSettings, log: Callable[[str], None]) -> dict[str, object]:
    """Whether the loop structure of ``new`` replaces ``old``'s, by the one criterion.

    ``J = n_eff ln(SSE / n) + penalty k`` (:mod:`~fricbench.sysid.diagnose.criterion`) on each
    diagnosis' free-run error of the whole training run, Akaike's own estimate of the held-out
    error: ``k`` counts the final model's free parameters (loop gains, damping, effects; plus
    ``extra_params`` for what the new structure fixed from the data beforehand, a drive
    limit's level), ``n_eff`` is that of the residual of the structure with more parameters
    (:func:`~fricbench.sysid.diagnose.criterion.comparison_samples`). Not blocked folds, as
    the effect search uses: a whole loop refitted on half the run extrapolates its gains
    to the other half by far more than either structure misses it by (measured on a
    second-simulator tuning run, a PID at 1 kHz logged at 100 Hz: 16 um in-sample, 290 um on
    the held-out fold), so the folds judge the fold fit, not the structure. A new structure
    whose free run diverges never wins. Returns the decision, JSON-ready.
    """
    out: dict[str, object] = {"candidate": what}
    if not new.finite or new.bounds is None or old.bounds is None:
        out.update(accepted=False, why="its free run of the training run diverges")
        log(f"  {what}: diverges, rejected")
        return out
    out.update(_judged(new, new.sse, old, old.sse, old.prep.x - old.train.y_after,
                       extra_params, settings))
    n = int(old.prep.n)
    log(f"  {what}: position rms {math.sqrt(new.sse / n):.4g} against "
        f"{math.sqrt(old.sse / n):.4g} m, criterion "
        f"{cast(float, out.get('criterion_change', math.inf)):+.3g}: "
        f"{'kept' if out['accepted'] else 'rejected'}")
    return out


def _n_params(fit: _ModeFit) -> int:
    """Free parameters of a diagnosis' final model on the position: its loop's gains when
    they were fitted to the position (a cascade or PID), its plant and its effects; a law
    identified from the effort was fitted to other data and is not counted."""
    assert fit.bounds is not None
    return len(position_params(fit.search.final.model, fit.bounds, controller=True))


def _judged(new: _ModeFit, sse_new: float, old: _ModeFit, sse_old: float,
            residual_old: np.ndarray, extra_params: int, settings: DiagnoseSettings
            ) -> dict[str, object]:
    """The criterion's decision between two diagnoses of one run, JSON-ready.

    ``J = n_eff ln(SSE / n) + penalty k`` on their free-run position errors ``sse_new`` and
    ``sse_old`` of the whole run, ``k`` from :func:`_n_params` (``extra_params`` more for the
    new one), ``n_eff`` that of the residual (``new``'s free run of the training run, or
    ``residual_old``) of the one with more parameters
    (:func:`~fricbench.sysid.diagnose.criterion.comparison_samples`). Keys: ``accepted``,
    ``why``, ``n_params``, ``n_params_other``, ``n_eff``, and the finite ones of
    ``position_rms_m``, ``position_rms_other_m`` and ``criterion_change``.
    """
    k_new = _n_params(new) + extra_params
    k_old = _n_params(old)
    n = int(old.prep.n)
    n_eff = comparison_samples(residual_old, new.prep.x - new.train.y_after, k_old, k_new,
                               settings.max_lag_share)
    change = criterion_change(sse_new, sse_old, k_new, k_old, n_eff, settings.penalty)
    accepted = bool(change < 0.0)
    out: dict[str, object] = {
        "accepted": accepted,
        "why": "lowers the criterion" if accepted else "does not lower the criterion",
        "n_params": k_new, "n_params_other": k_old, "n_eff": n_eff}
    # finite numbers only (the other structure's run may have diverged)
    for key, sse in (("position_rms_m", sse_new), ("position_rms_other_m", sse_old)):
        if math.isfinite(sse):
            out[key] = math.sqrt(sse / n)
    if math.isfinite(change):
        out["criterion_change"] = change
    return out


def _fast_loop_note(prep: Prepared, n_fast: int, cost: float, slow_cost: float, what: str
                    ) -> str:
    """The report's note on a loop simulated faster than the log."""
    return (f"the loop is simulated at {1e3 * prep.inputs.ts / n_fast:.3g} ms, {n_fast} periods "
            f"per logged sample ({what} it leaves {100 * cost / slow_cost:.2g} % of the squared "
            "position error of a loop at the log's rate)")


def _search_position(base: _LoopBase, run: RunData, settings: DiagnoseSettings,
                     log: Callable[[str], None], t0: float,
                     effort_check: InverseDynamics | None, fast_note: str | None = None
                     ) -> _ModeFit:
    """The forward selection on the position from one loop base (at the log's rate or
    faster, ``fast_note`` then saying so)."""
    notes = ["no effort column: forces are reported per unit mass (m/s^2)"]
    if fast_note is not None:
        notes.append(fast_note)
    warnings: list[str] = []
    laws = {"train": "a cascade fitted to the training run's position"}
    prep, linear, y_lin, bounds, jac, alt = (base.prep, base.linear, base.y_lin, base.bounds,
                                             base.jac, base.alt)
    log(f"  linear position rms {_rms(prep.x - y_lin) * run.logged_unit.per_si:.4g} "
        f"{run.logged_unit.display} ({time.perf_counter() - t0:.1f} s)")
    limit = base.limit
    if limit is not None:
        warnings.append(
            f"the drive clips: a limit of {limit.level:.4g} m/s^2 per unit mass on the "
            f"loop's command, identified from the position alone (the loop "
            f"with it clips {100 * limit.clipped_share:.1f} % of the samples and leaves "
            f"{100 * limit.sse_ratio:.2g} % of the squared error without it); every "
            "model of the run clips there")
        log(f"  warning: {warnings[-1]}")
    if alt:
        log(f"  loop gains identified with friction: {alt[0].to_dict()}")
    # the loop fitted with the limit is a start of that effect's fits (with its own loop,
    # boxed), and so is the loop fitted with friction when it brought a command delay: the
    # linear loop refitted under that delay is far from it, and the search's own starts, a
    # Coulomb level from the linearised screen under that loop, stayed there (control/10 of the
    # second simulator, a PID with a 3-sample delay: 215 urad left where this start leaves
    # 5.3). Without a delay it is not a start: from a fast loop at a 100 Hz log's rate its
    # small friction fitted best on the training half and was rejected as too small, where
    # the search's own start found the friction (control/2)
    delayed = (base.with_friction is not None
               and base.with_friction.plant[CL.I_DELAY] > 0)
    starts = ((limit.model,) if limit is not None
              else (base.with_friction,) if delayed and base.with_friction is not None
              else ())
    search = forward_selection(linear, y_lin, prep, bounds, idim=None, w=None, jac=jac,
                               settings=settings, alt_loops=alt, alt_starts=starts,
                               effort_check=effort_check, log=log)
    log(f"stop: {search.stop_reason}")
    final = search.final.model
    if isinstance(final.controller, CascadeController) and final.controller.is_pid:
        g = final.controller.pid_gains(prep.inputs.loop_ts)
        # a filter pole on its lower bound 0 reads as a time constant of a few nanoseconds
        flt = ("no derivative filter"
               if g["tf_s"] < defaults().no_filter_share * prep.inputs.loop_ts
               else f"derivative filter {1e3 * g['tf_s']:.3g} ms")
        laws["train"] = ("a PID position loop fitted to the training run's position with "
                         f"friction (per unit mass: P {g['p_1_s2']:.4g} 1/s^2, I "
                         f"{g['i_1_s3']:.4g} 1/s^3, D {g['d_1_s']:.4g} 1/s, {flt}); the "
                         "linear model's loop is a cascade")
    delay = int(final.plant[CL.I_DELAY])
    if delay > 0:
        laws["train"] += (f"; every model's command is delayed by {delay} loop period"
                          f"{'s' if delay > 1 else ''} ({1e3 * delay * prep.inputs.loop_ts:.3g}"
                          " ms), found with the friction")
    train = _evaluate(linear, final, prep)
    return _ModeFit("position", "m_s2", prep, linear, search, train, notes, warnings, laws,
                    bounds=bounds)


def _better_of(effort: _ModeFit, run: RunData, prep_pos: Prepared, ctrl_err: float,
               settings: DiagnoseSettings, log: Callable[[str], None],
               t0: float, idim: InverseDynamics | None = None) -> _ModeFit:
    """The effort's diagnosis, or the position's when the criterion prefers it.

    A law identified from a logged effort reproduces the drive's loop only when the log holds
    what the controller read and computed, at the loop's rate: an effort logged slower than the
    loop runs, a position fed back from another sensor (a semi-closed loop) or a delay before
    the force break that, and the law's loop then predicts the position worse than a loop
    fitted to the position with friction. The position decides (the issue's fallback to the
    position-only search) by the one criterion (:func:`_judged`: the position's loop counts
    its fitted gains, the effort's law, fitted to the effort, counts none), and the report
    says why.
    """
    n = effort.prep.x.shape[0]
    sse_e = effort.sse
    r_e = effort.prep.x - effort.train.y_after
    if effort.train.used_injected:
        # compared from the reference alone, as the position's loop runs: the effort the law
        # leaves, fed back as an input, carries the drive's reaction to the very effects the
        # position's diagnosis looks for (a drift, a lag), and would win the comparison for it
        y_e, _ = simulate_position(effort.search.final.model, effort.prep)
        r_e = effort.prep.x - y_e
        sse_e = float(np.sum(r_e**2)) if np.all(np.isfinite(r_e)) else math.inf
    rms_e = math.sqrt(sse_e / n)
    if rms_e <= settings.floor_factor * effort.search.floor:
        return effort  # at the noise floor: nothing a loop fitted to the position could add
    log("checking the effort's loop against a loop fitted to the position alone")
    try:
        pos = _fit_position(run, prep_pos, settings, log, t0, effort_check=idim)
    except DiagnosisError:
        return effort
    rms_p = math.sqrt(pos.sse / n)
    eff: dict[str, object] = {"effects": _effects(effort),
                              "law_relerr_pct": ctrl_err,
                              "injected_effort_left_out": effort.train.used_injected}
    if math.isfinite(rms_e):
        eff["position_rms_m"] = rms_e
    else:
        eff["diverged"] = True
    comparison: dict[str, object] = {
        "rule": "the position alone when it lowers the criterion J = n_eff ln(SSE / n) + "
                f"{settings.penalty:g} k on the free-run position error (k: the parameters "
                "each diagnosis fitted to the position)",
        "effort": eff}
    if not pos.finite or pos.bounds is None or effort.bounds is None:
        comparison["position"] = {"effects": _effects(pos), "diverged": True}
        effort.comparison = dict(comparison, chosen="effort")
        return effort
    comparison["position"] = {"effects": _effects(pos), "position_rms_m": rms_p}
    # a free run of the effort's law that diverged leaves no residual to count samples on:
    # the position's own stands in (its criterion change is then -inf whatever n_eff)
    judged = _judged(pos, pos.sse, effort, sse_e,
                     r_e if math.isfinite(sse_e) else pos.prep.x - pos.train.y_after, 0,
                     settings)
    comparison["criterion"] = {k: v for k, v in judged.items()
                               if k in ("n_params", "n_params_other", "n_eff",
                                        "criterion_change")}
    log(f"  the position's loop against the effort's: criterion "
        f"{cast(float, judged.get('criterion_change', -math.inf)):+.3g}")
    if not judged["accepted"]:
        effort.comparison = dict(comparison, chosen="effort")
        return effort
    pos.comparison = dict(comparison, chosen="position")
    shown = run.logged_unit
    unit, k = shown.display, shown.per_si
    alone = (" from the reference alone (without the effort the law leaves unexplained)"
             if effort.train.used_injected else "")
    with_e = ", ".join(_effects(effort)) or "no effect"
    worse = (f"worse ({k * rms_e:.4g} {unit} rms with {with_e})" if math.isfinite(rms_e)
             else f"not at all (with {with_e}, its free run diverges)")
    why = (f"the loop of the control law identified from the effort predicts the position"
           f"{alone} {worse} "
           f"than a loop fitted to the position with friction ({k * rms_p:.4g} {unit}): the law "
           "does not reproduce the drive's loop (an effort logged slower than the loop runs, "
           "a position fed back from another sensor, a delay); the diagnosis runs on the "
           "position alone (forces per unit mass)")
    log("  the effort's loop is set aside: the diagnosis runs on the position alone")
    pos.warnings.insert(0, why)
    # the position search's first note says no effort was logged; the others (the loop's
    # rate) hold
    pos.notes = ["forces are reported per unit mass (m/s^2): the effort's law was set aside "
                 "(see the warnings)", *pos.notes[1:]]
    return pos


def _effects(fit: _ModeFit) -> list[str]:
    return [st.effect for st in fit.search.steps[1:] if st.effect is not None]


def _profile_statistics(final: GreyBox, names: list[str], fit: _ModeFit, n_eff: float
                        ) -> dict[str, tuple[float, float]]:
    """:func:`~fricbench.sysid.diagnose.criterion.profile_statistic` of each of ``names`` in
    ``final``, with the ratio of the squared errors.

    ``final`` and ``final`` without each name are refitted on the training run's free-run
    position, every parameter the Jacobian of :func:`model_uncertainty` moves free, from the
    final model's values (the same fit for all, so none wins by its start): ``final``'s fit
    once, whatever the number of names, all of them at once.
    """
    if not names:
        return {}
    assert fit.bounds is not None
    w = _injected(final, fit.prep)[0]
    fits = run_concurrently([
        partial(PositionFit(fit.prep, position_params(m, fit.bounds, controller=True,
                                                      effects=list(m.effects)), None, w).run,
                m, max_iter=12) for m in (final, *(final.without(e) for e in names))])
    with_cost = fits[0].cost
    return {e: (profile_statistic(with_cost, f.cost, n_eff),
                f.cost / with_cost if with_cost > 0.0 else math.inf)
            for e, f in zip(names, fits[1:], strict=True)}


def diagnose(run: RunData, *, validate: RunData | None = None, force_unit: str = "N",
             settings: DiagnoseSettings | None = None, compare_tf: bool = False,
             cutoff_hz: float | None = None, decim: int | None = None,
             quantum: float | None = None,
             log: Callable[[str], None] | None = None) -> DiagnosisResult:
    """Find the effects a linear model of the run lacks, add them, report the errors.

    Parameters
    ----------
    run : RunData
        The run to diagnose (see :func:`fricbench.sysid.io.load_run`).
    validate : RunData, optional
        Another run of the same axis: the final model, fitted on ``run``, is evaluated on it.
    force_unit : str
        Unit of the effort column, used to label force parameters (``"N"``, ``"A"``, ``"V"``).
        Without an effort, forces are per unit mass (``m_s2``).
    settings : DiagnoseSettings, optional
        The diagnosis' settings (default: :func:`~fricbench.sysid.diagnose.settings.defaults`).
    compare_tf : bool
        Also fit the black-box transfer function of ``fricbench.sysid.tf_fit`` and report its
        position error (slow on long runs).
    cutoff_hz, decim : optional
        Derivative filter (Hz, below the Nyquist frequency) and decimation (an integer >= 1)
        of the inverse dynamics (defaults: a tenth of the sampling rate, 10).
    quantum : float, optional
        The position sensor's step, in the run's SI unit (m or rad), when known; otherwise it
        is detected from the data (see :func:`fricbench.sysid.diagnose.signals.noise_floor`).
    log : callable, optional
        Receives progress lines.

    Returns
    -------
    DiagnosisResult

    Raises
    ------
    TypeError
        ``run`` or ``validate`` is not a RunData.
    ValueError
        ``decim`` or ``cutoff_hz`` out of range, or the two runs sampled at different times.
    """
    if not isinstance(run, RunData):
        raise TypeError(f"run={run!r}: expected a RunData (fricbench.sysid.io.load_run)")
    if validate is not None and not isinstance(validate, RunData):
        raise TypeError(f"validate={validate!r}: expected a RunData or None")
    if validate is not None and abs(validate.ts - run.ts) > 0.01 * run.ts:
        raise ValueError(f"validate: sampled at ts={validate.ts:g} s but the run at "
                         f"ts={run.ts:g} s: expected the same sample time")
    if decim is not None and (isinstance(decim, bool) or not isinstance(decim, (int, np.integer))
                              or decim < 1):
        raise ValueError(f"decim={decim!r}: expected an integer >= 1 (1: no decimation) or None")
    settings = defaults() if settings is None else settings
    log = log or (lambda _s: None)
    t0 = time.perf_counter()
    prep = prepare(run, cutoff_hz=cutoff_hz, decim=decim, quantum=quantum)
    notes: list[str] = []
    warnings: list[str] = []
    laws: dict[str, str] = {}
    if prep.saturation is not None:
        sat = prep.saturation
        warnings.append(f"the effort saturates at {sat.level:.4g} {force_unit} "
                        f"({100 * sat.share:.2f} % of the samples): those samples are left out "
                        "of the law and friction fits, and the simulated drive clips there")
    if prep.filter_source == "sensor resolution":
        notes.append(f"derivative filter {prep.cutoff_hz:.3g} Hz and decimation {prep.decim} "
                     "chosen from the sensor resolution against the motion's mean speed (the "
                     "recipe's tenth of the sampling rate would differentiate the sensor's "
                     "steps); --filter-hz and --decimate override")
    prep0 = prep
    search_settings = settings

    def fit_modes(settings: DiagnoseSettings) -> tuple[_ModeFit, list[str], dict[str, str]]:
        """The loop and the effects of the run, searched among ``settings.candidates``."""
        prep = prep0
        warnings: list[str] = []
        laws: dict[str, str] = {}
        fit: _ModeFit | None = None
        prep_pos = prep
        if prep.u is not None:
            log("linear model: controller law from the effort, inverse dynamics u = M a + B v")
            linear, idim, bounds, ctrl_err = fit_linear_with_effort(prep)
            # the effort's free runs judge its forces at a finer step (see settings.effort_max_step)
            prep = dataclasses.replace(prep, n_sub=max(prep.n_sub, substeps(
                prep.inputs.loop_ts, 1, max_step=settings.effort_max_step)))
            w, share, used = _injected(linear, prep)
            y_lin, _ = simulate_position(linear, prep, w)
            why = _law_unusable(prep, y_lin)
            prep_pos = prepare(dataclasses.replace(run, u=None), cutoff_hz=cutoff_hz, decim=decim,
                               quantum=quantum)
            if why is not None:
                warnings.append(f"{why}: the effort is not used for the loop; the diagnosis runs "
                                "on the position alone (forces per unit mass)")
                log(f"warning: {warnings[-1]}")
            else:
                fit = _fit_effort(run, prep, linear, idim, bounds, ctrl_err, y_lin,
                                  (w, share, used), force_unit, settings, log, t0)
                if (ctrl_err > settings.law_exact_pct or not fit.finite
                        or int(round(prep.ts / settings.loop_ts)) >= 2):
                    fit = _better_of(fit, run, prep_pos, ctrl_err, settings, log, t0, idim)
                    if fit.mode == "position" and fit.comparison is not None:
                        # what the per-unit-mass forces are in the effort's unit: the mass the
                        # inverse dynamics gives with Coulomb friction (none when it is not
                        # identified: on its zero bound, the effort then says nothing of it)
                        mass = float(idim.fit(("coulomb_friction",), CL.default_plant(1.0, 0.0))[
                            CL.I_M])
                        if mass > 0.0 and math.isfinite(mass):
                            fit.comparison["effort_mass"] = {
                                f"mass_{force_unit}_s2_m": mass,
                                "note": "inverse dynamics with Coulomb friction: a force per unit "
                                        f"mass times this is the force in {force_unit}"}
        if fit is None:
            # a law that cannot drive the loop leaves the effort a measured force all the same
            fit = _fit_position(run, prep_pos, settings, log, t0,
                                effort_check=idim if prep.u is not None else None)
        return fit, warnings, laws

    fit, fit_warnings, fit_laws = fit_modes(search_settings)
    undetected: list[str] = []
    not_detected: list[dict[str, object]] = []
    # effects the profile form of the test detected in the final model, and why
    profile_detected: dict[str, dict[str, float]] = {}
    profile_warnings: list[str] = []
    uncertainty = None
    tried = effects_tried(search_settings)
    for _ in range(len(tried)):
        profile_detected, profile_warnings = {}, []
        if fit.bounds is None or not fit.finite:
            break
        final = fit.search.final.model
        uncertainty = model_uncertainty(final, fit.prep, fit.bounds,
                                        _injected(final, fit.prep)[0],
                                        force_unit=fit.force_unit, settings=search_settings)
        # an effect another one needs (Coulomb friction under a Stribeck hump) stays with it
        needed = {r for e in final.effects for r in get_effect(e).requires}
        within = [e for e in uncertainty.within(search_settings.detection_sd)
                  if e not in needed and e in tried]
        # the Jacobian's test is the linearised (Wald) form; a size the fit is far from linear
        # in (a friction level that moves every stick-slip stop) can lie within its sd while
        # the data cannot do without it: the profile (likelihood-ratio) form of the same test
        # at the same level decides then (Bates & Watts 1988, ch. 6; Seber & Wild 1989, 5.9)
        profiles = _profile_statistics(final, within, fit, uncertainty.n_eff)
        for name in list(within):
            stat, ratio = profiles[name]
            if stat > search_settings.detection_sd ** 2:
                within.remove(name)
                profile_detected[name] = {
                    "size_over_sd": uncertainty.size_over_sd[name],
                    "profile_statistic": stat, "sse_ratio": ratio}
                profile_warnings.append(
                    f"{name}: its size lies within {search_settings.detection_sd:g} standard "
                    "deviations of zero by the Jacobian (|size|/sd "
                    f"{uncertainty.size_over_sd[name]:.3g}), but the model refitted without it "
                    f"leaves {ratio:.3g} times the squared error of the training run's free run "
                    f"(n_eff ln ratio = {stat:.3g} > {search_settings.detection_sd ** 2:g}, "
                    "the same test without the linearisation): detected, its reported "
                    "standard deviation the linearised one")
                log(f"warning: {profile_warnings[-1]}")
        if not within:
            break
        # a size the data cannot tell from zero is not detected: the least significant such
        # effect leaves the candidates and the search runs again without it, as an effect a
        # later one made redundant does (the open loop refits without it)
        name = min(within, key=lambda e: uncertainty.size_over_sd[e])  # type: ignore[union-attr]
        not_detected.append({"effect": name,
                             "size_over_sd": uncertainty.size_over_sd[name],
                             "n_eff": uncertainty.n_eff,
                             "parameters": describe_parameters(name, final.plant,
                                                               fit.force_unit),
                             "sd": uncertainty.sd[name]})
        undetected.append(f"{name}: not detected (the held-out error named it, but its fitted "
                          f"size lies within {search_settings.detection_sd:g} standard "
                          "deviations of zero: |size|/sd "
                          f"{uncertainty.size_over_sd[name]:.3g}, the residual worth "
                          f"{uncertainty.n_eff:.3g} independent samples); the search ran "
                          "again without it")
        log(f"warning: {undetected[-1]}")
        tried = tuple(c for c in tried if c != name)
        search_settings = dataclasses.replace(search_settings, candidates=tried)
        fit, fit_warnings, fit_laws = fit_modes(search_settings)
        uncertainty = None
    warnings += fit_warnings + undetected + profile_warnings
    laws.update(fit_laws)
    prep, mode, fu, linear, search, train = (fit.prep, fit.mode, fit.force_unit, fit.linear,
                                             fit.search, fit.train)
    final = search.final.model
    notes += fit.notes
    warnings += fit.warnings
    laws.update(fit.laws)
    tf = fit_linear_tf(prep) if compare_tf else None
    val_eval = None
    val_coverage = None
    if validate is not None:
        # a model per unit mass (position mode) cannot use an effort in the drive's unit: the
        # validation run is read without it, as the training run was (its first effort would
        # otherwise start the loop's integrator in the wrong unit)
        v_run = (dataclasses.replace(validate, u=None)
                 if mode == "position" and validate.u is not None else validate)
        # the training run's integration step too (substeps per logged sample): the model is
        # simulated as it was fitted
        prep_v = prepare(v_run, cutoff_hz=prep.cutoff_hz, decim=prep.decim, quantum=quantum,
                         n_sub=prep.n_sub * prep.inputs.n_loop)
        # the training run's loop rate (a property of the drive, as its gains are)
        prep_v = prep_v.with_loop(prep.inputs.n_loop)
        law_v = None
        if mode == "effort" and prep_v.u is not None:
            # the plant is what is validated; the loop is the validation run's own: its law
            # (it may be another controller, or other gains) identified from its effort,
            # through the prefilter the training run chose (a property of the log, not of the
            # controller), so that the validation position never chooses its own law
            assert isinstance(linear.controller, ArxController)
            law_v = fit_law_like(prep_v, linear.controller)
            laws["validation"] = ("identified on the validation run "
                                  f"({law_v.relerr_pct:.2f} % relative error)"
                                  f"{_clamped_words(law_v)}")
        else:
            laws["validation"] = f"the training run's ({laws['train']})"
        val_eval = _evaluate(linear, final, prep_v, law_v)
        val_coverage = coverage(prep, prep_v)
        warnings += val_coverage.warnings(prep)
        if validate.u is None and prep.u is not None:
            notes.append("the validation run has no effort: only position metrics")
        if not np.all(np.isfinite(val_eval.y_after)):
            warnings.append("the final model diverges on the validation run")
    if not fit.finite:
        raise DiagnosisError("the fitted loop diverges in a free run of the training run: no "
                             "valid model of this run")
    warnings += search.warnings
    lines, floor = _sensor_disturbance(prep, search.floor, train.y_after, settings)
    if lines:
        warnings.append(disturbance_warning(lines, run.logged_unit.display,
                                            1.0 / run.logged_unit.per_si))
        log(f"warning: {warnings[-1]}")
    if not mains_visible(prep.ts, settings):
        notes.append(f"the log's Nyquist frequency ({0.5 / prep.ts:.4g} Hz) leaves no room for "
                     f"the mains' lines ({min(settings.mains_hz):g} Hz and above, with the band "
                     "around them): a hum of the sensor could not be told from motion, and none "
                     "was sought")
    if uncertainty is None and fit.bounds is not None and fit.finite:
        uncertainty = model_uncertainty(final, prep, fit.bounds,
                                        _injected(final, prep)[0], force_unit=fu,
                                        settings=search_settings)
    if uncertainty is not None:
        # what stays although within its uncertainty: an effect another one needs
        for name in uncertainty.within(search_settings.detection_sd):
            if name in profile_detected:
                continue  # its warning above says why it stays
            warnings.append(
                f"{name}: kept, as an effect of the model needs it, but its fitted size lies "
                f"within {search_settings.detection_sd:g} standard deviations of zero "
                f"(|size|/sd {uncertainty.size_over_sd[name]:.3g}): weakly determined")
            log(f"warning: {warnings[-1]}")
    return DiagnosisResult(run=run, prep=prep, mode=mode, force_unit=fu, linear=linear,
                           search=search, train=train, validation=val_eval,
                           validation_run=validate, linear_tf=tf,
                           elapsed_s=time.perf_counter() - t0, notes=notes, laws=laws,
                           diagnosis_warnings=warnings, mode_comparison=fit.comparison,
                           validation_coverage=val_coverage, uncertainty=uncertainty,
                           not_detected=not_detected, profile_detected=profile_detected,
                           loop_decisions=fit.loop_decisions,
                           sensor_lines=lines, floor=floor)
