"""Running ``fricbench diagnose`` on a second-simulator case and judging its report.

Shared by ``test_diagnose_second_sim.py`` and ``sweep_second_sim.py``. The diagnosis is run
the way a user runs it: the case is written as a CSV (:func:`second_sim.write_csv`) and the
real command line (:func:`fricbench.cli.main`) is called in-process with the options a user
would give (:func:`second_sim.cli_args`) and ``--json``.

A diagnosis is right when

* the command exits with status 0 and prints no traceback (nor raises);
* the JSON report holds no NaN, inf or null anywhere;
* the case's effect is named (none for a control) and no other effect is, friction
  descriptions (Coulomb, Stribeck, asymmetric friction, force offset) aside;
* the position rms error falls at least 2x against the linear model, or to within 1.5x the
  case's noise floor.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import time
import traceback
from dataclasses import dataclass, field

import second_sim as S

__all__ = ["Outcome", "diagnose_case", "judge", "bad_numbers", "format_row", "HEADER"]


@dataclass
class Outcome:
    """What one diagnosis run gave and whether it is right.

    Attributes
    ----------
    case : second_sim.Case
    status : int or None
        Exit status (None when the command raised).
    report : dict or None
        The JSON report, when one was written and parsed.
    stdout, stderr : str
    failures : list of str
        Why the diagnosis is not right (empty when it is).
    elapsed : float
        Wall time of the command, s.
    bad : list of str
        Key paths of the null, NaN and inf values in the report.
    """

    case: S.Case
    status: int | None
    report: dict | None
    stdout: str
    stderr: str
    failures: list[str] = field(default_factory=list)
    elapsed: float = 0.0
    bad: list[str] = field(default_factory=list)

    @property
    def wrong_only_by_candidate_nulls(self) -> bool:
        """Whether the only fault is null or non-finite numbers inside the candidate lists
        (``candidates``, ``rejected_at_last_step``), where the report marks candidates that
        were ranked but not fitted: for telling that fault apart in the sweep's summary."""
        return (len(self.failures) == 1 and self.failures[0].startswith("non-finite")
                and all(".candidates[" in p or p.startswith(("candidates[",
                                                              "rejected_at_last_step["))
                        for p in self.bad))

    @property
    def ok(self) -> bool:
        """Whether the diagnosis is right."""
        return not self.failures

    @property
    def effects(self) -> list[str]:
        """Effects the report names (empty without a report)."""
        return list(self.report.get("effects", [])) if self.report else []


def position_only(case: S.Case, workdir: str | os.PathLike[str]) -> object:
    """The case's run as the diagnosis prepares it, without its effort (a ``Prepared``): the
    CSV written, read back with the command line's own column arguments."""
    import argparse

    from fricbench.sysid.diagnose.command import _configure
    from fricbench.sysid.diagnose.prepared import prepare
    from fricbench.sysid.io import load_run

    path = os.path.join(str(workdir), f"{case.kind}-{case.seed}-position.csv")
    S.write_csv(case, path)
    ns = _configure(argparse.ArgumentParser()).parse_args(S.cli_args(case, path))
    run = load_run(path, time=ns.time, reference=ns.reference, position=ns.position,
                   effort=None, sample_time=ns.sample_time, position_unit=ns.position_unit)
    return prepare(run)


def true_pid_loop(case: S.Case) -> object:
    """The case's PID law, delay and Coulomb friction as a grey box per unit mass (the mapping
    of :class:`CascadeController`'s docstring: ``wv = D kt / M``, ``kp = P / D``,
    ``kpi = I / D``, the derivative filter's pole ``T_f / (T_f + ts)``; the unfiltered velocity
    feedforward folded into ``kvff``), at the simulator's loop period."""
    from fricbench.axis import plant as PL
    from fricbench.sysid.diagnose import closed_loop as CL
    from fricbench.sysid.diagnose.controllers import CascadeController
    from fricbench.sysid.diagnose.models import GreyBox

    c, pl = case.ctrl, case.plant
    if c.law != "pid":
        raise ValueError(f"case {case.kind}/{case.seed}: law {c.law!r}, expected 'pid'")
    ctrl = CascadeController(wv=c.kt * c.d / pl.mass, kp=c.p / c.d, kvff=1.0 + c.ff1 / c.d,
                             kaff=c.kt * c.ff2 / pl.mass, kpi=c.i / c.d,
                             vel_pole=c.tf / (c.tf + S.LOOP_TS))
    row = CL.default_plant(1.0, pl.damping / pl.mass)
    row[PL.DELAY] = c.delay
    row[CL.I_FC] = pl.coulomb / pl.mass
    return GreyBox(ctrl, row, ("coulomb_friction",))


def friction_fit_against_truth(case: S.Case, workdir: str | os.PathLike[str]
                               ) -> tuple[object, object, float, float]:
    """The friction-aware fit of a PID case's run, without its effort, beside its true loop:
    ``(prep, fit, rms of the true loop, rms of the fit)``, m or rad."""
    import numpy as np

    from fricbench.sysid.diagnose.baselines import fit_linear_cascade, friction_aware_fit_scaled
    from fricbench.sysid.diagnose.models import simulate_position

    prep = position_only(case, workdir)
    y_true, _ = simulate_position(true_pid_loop(case), prep)  # type: ignore[arg-type]
    linear, _, bounds, _ = fit_linear_cascade(prep)  # type: ignore[arg-type]
    # the diagnosis's call (at the better of two force scales, a level on its bound raised)
    fit, _ = friction_aware_fit_scaled(linear, prep, bounds)  # type: ignore[arg-type]
    if fit is None:
        raise AssertionError(f"{case.kind}/{case.seed}: no friction-aware fit")
    x = prep.x  # type: ignore[attr-defined]
    return (prep, fit, float(np.sqrt(np.mean((x - y_true) ** 2))),
            float(np.sqrt(np.mean((x - fit.y) ** 2))))


def bad_numbers(obj: object, path: str = "") -> list[str]:
    """Key paths of the null, NaN and inf values anywhere in a parsed JSON document."""
    if isinstance(obj, dict):
        return [p for k, v in obj.items() for p in bad_numbers(v, f"{path}.{k}" if path else k)]
    if isinstance(obj, list):
        return [p for i, v in enumerate(obj) for p in bad_numbers(v, f"{path}[{i}]")]
    if obj is None:
        return [f"{path} = null"]
    if isinstance(obj, float) and not math.isfinite(obj):
        return [f"{path} = {obj}"]
    return []


def _last_line(text: str) -> str:
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    return lines[-1].strip() if lines else ""


def run_cli(argv: list[str], json_path: str
            ) -> tuple[int | None, dict | None, str, str, float, str | None]:
    """Run ``fricbench`` with ``argv`` in-process, as a user would, and read its JSON report.

    Returns the exit status (None after a traceback, which goes to the captured stderr), the
    report (None when absent or unreadable), the captured stdout and stderr, the wall time
    and why the JSON could not be parsed (None when it could). NaN and Infinity are read
    as numbers so that a judge can name them rather than fail the parse.
    """
    from fricbench.cli import main

    out, err = io.StringIO(), io.StringIO()
    t0 = time.perf_counter()
    status: int | None
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status = main(argv)
        except SystemExit as exc:  # argparse refusing an option
            status = exc.code if isinstance(exc.code, int) else 2
        except Exception:  # a traceback a user would see
            traceback.print_exc()
            status = None
    elapsed = time.perf_counter() - t0
    report = None
    parse_error = None
    if os.path.exists(json_path):
        with open(json_path, encoding="utf-8") as fh:
            text = fh.read()
        try:
            report = json.loads(text, parse_constant=lambda c: float(c.replace("Infinity",
                                                                               "inf")))
        except ValueError as exc:
            parse_error = str(exc)
    return status, report, out.getvalue(), err.getvalue(), elapsed, parse_error


def diagnose_case(case: S.Case, workdir: str | os.PathLike[str],
                  extra_args: tuple[str, ...] = ()) -> Outcome:
    """Write ``case`` as a CSV in ``workdir``, run ``fricbench diagnose`` on it in-process
    with ``--json`` and judge the result (see :func:`judge`)."""
    stem = os.path.join(os.fspath(workdir), f"{case.kind}-{case.seed}")
    csv_path, json_path = stem + ".csv", stem + ".json"
    S.write_csv(case, csv_path)
    if os.path.exists(json_path):
        os.remove(json_path)
    argv = ["diagnose", *S.cli_args(case, csv_path), "--json", json_path, "--quiet",
            *extra_args]
    status, report, stdout, stderr, elapsed, parse_error = run_cli(argv, json_path)
    outcome = Outcome(case, status, report, stdout, stderr, elapsed=elapsed)
    outcome.failures = judge(outcome, parse_error)
    return outcome


def run_failures(status: int | None, stderr: str, report: dict | None,
                 parse_error: str | None) -> list[str]:
    """What went wrong with the command itself, whatever the run: a traceback, a non-zero
    exit, an unreadable or missing JSON report, a null, NaN or inf in it."""
    failures = []
    if status is None or "Traceback (most recent call last)" in stderr:
        failures.append(f"traceback: {_last_line(stderr)}")
    elif status != 0:
        failures.append(f"exit {status}: {_last_line(stderr)}")
    if parse_error is not None:
        failures.append(f"JSON unreadable: {parse_error}")
    if report is None:
        if status == 0:
            failures.append("exit 0 without a JSON report")
        return failures
    bad = bad_numbers(report)
    if bad:
        more = f" (+{len(bad) - 1} more)" if len(bad) > 1 else ""
        failures.append(f"non-finite {bad[0]}{more}")
    return failures


def named_effects(report: dict) -> set[str]:
    """The effects a report names, each further term of an effect (a harmonic of the cogging:
    ``Effect.refines``) counted as that effect."""
    from fricbench.sysid.diagnose.effects import named_as

    return {named_as(e) for e in report.get("effects", [])}


def judge(outcome: Outcome, parse_error: str | None = None) -> list[str]:
    """Why ``outcome`` is not a right diagnosis of its case (empty list: it is)."""
    case = outcome.case
    failures = run_failures(outcome.status, outcome.stderr, outcome.report, parse_error)
    report = outcome.report
    if report is None:
        return failures
    outcome.bad = bad_numbers(report)
    effects = named_effects(report)
    present = S.EFFECT_NAME[case.kind]
    allowed = S.FRICTION_NAMES | ({present} if present else set())
    if present is not None and present not in effects:
        failures.append(f"missed {present}")
    if effects - allowed:
        failures.append(f"named absent {','.join(sorted(effects - allowed))}")
    pos = report.get("position") or {}
    before, after = pos.get("rms_before"), pos.get("rms_after")
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (before, after)):
        failures.append(f"position rms {before} -> {after}")
    elif after > max(0.5 * before, 1.5 * case.floor):
        failures.append(f"rms {before:.3g} -> {after:.3g} (x{before / max(after, 1e-300):.2f}), "
                        f"floor {case.floor:.3g}")
    return failures


HEADER = (f"{'case':13s} {'variant':42s} {'present':10s} {'named':44s} "
          f"{'rms before -> after (floor), um|urad':38s} {'verdict':18s} {'ok':4s} "
          f"{'time':>6s}  reason")

_SHORT = {"coulomb_friction": "coulomb", "stribeck_friction": "stribeck",
          "asymmetric_friction": "asym", "force_offset": "offset", "backlash": "backlash",
          "cogging": "cogging", "thermal_drift": "thermal", "position_dependent_friction": "posdep"}


def format_row(outcome: Outcome) -> str:
    """One line of the sweep's table."""
    case = outcome.case
    rep = outcome.report or {}
    pos = rep.get("position") or {}

    def um(v: object) -> str:
        return f"{v * 1e6:.3g}" if isinstance(v, (int, float)) and math.isfinite(v) else str(v)

    rms = (f"{um(pos.get('rms_before'))} -> {um(pos.get('rms_after'))} "
           f"({um(case.floor)})") if pos else "-"
    named = ",".join(_SHORT.get(e, e) for e in outcome.effects) or "-"
    present = _SHORT.get(S.EFFECT_NAME[case.kind] or "", "-") or "-"
    verdict = str(rep.get("verdict", "-"))
    reason = "; ".join(outcome.failures)
    return (f"{case.kind + '/' + str(case.seed):13s} {case.variant.label():42s} {present:10s} "
            f"{named:44s} {rms:38s} {verdict:18s} {'ok' if outcome.ok else 'FAIL':4s} "
            f"{outcome.elapsed:5.1f}s  {reason}")
