"""Running ``fricbench diagnose`` on a third-simulator run and judging its report.

The run is written as its machine's logger writes it (:meth:`third_sim.Case.write_csv`) and the
real command line is called in-process with the options a user would type
(:meth:`third_sim.Case.cli_args`) and ``--json``.

What counts as right (:func:`judge`), per run:

* the command exits 0 without a traceback, and its JSON holds no NaN, inf or null;
* every effect the kind requires is named (:data:`third_sim.REQUIRED`: Stribeck friction for
  the PWM motor, the LuGre axis and the open-loop runs; cogging for the linear motor; thermal
  drift for the warming screw; position-dependent friction for the rotary table; backlash for
  the velocity-loop drive; compliance for the belt), and for the vertical axis at least one of
  a force offset or an asymmetric friction (gravity, :data:`third_sim.ONE_OF`);
* no axis effect the machine lacks is named (backlash, cogging, thermal drift, position-
  dependent friction, compliance): on the controls, the hum and the jittered log that is every
  one of them. Friction descriptions (Coulomb, Stribeck, asymmetric, force offset) are never
  wrong;
* the hum's run: the verdict does not call the residual a resonance (the hum is the sensor's);
* the jittered log: diagnosed (not refused), with a warning that it was resampled;
* the free-run position error falls at least 2x against the linear model, or to within 1.5 noise
  floors (the floor counts the sensor's noise, quantisation and hum).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import third_sim as S
from second_sim_check import bad_numbers, named_effects, run_cli, run_failures

__all__ = ["Outcome", "diagnose_case", "judge", "bad_numbers"]


@dataclass
class Outcome:
    """What one diagnosis gave and why it is not right (``failures`` empty: it is)."""

    case: S.Case
    status: int | None
    report: dict | None
    stdout: str
    stderr: str
    failures: list[str] = field(default_factory=list)
    elapsed: float = 0.0

    @property
    def ok(self) -> bool:
        """Whether the diagnosis is right."""
        return not self.failures

    @property
    def effects(self) -> list[str]:
        """Effects the report names (empty without a report)."""
        return list(self.report.get("effects", [])) if self.report else []


def diagnose_case(case: S.Case, workdir: str | os.PathLike[str],
                  extra_args: tuple[str, ...] = ()) -> Outcome:
    """Write ``case`` in ``workdir``, run ``fricbench diagnose ... --json`` on it in-process and
    judge the report."""
    stem = os.path.join(os.fspath(workdir), f"third-{case.kind}-{case.seed}")
    csv_path, json_path = stem + (".tsv" if case.sep == "\t" else ".csv"), stem + ".json"
    case.write_csv(csv_path)
    if os.path.exists(json_path):
        os.remove(json_path)
    argv = ["diagnose", *case.cli_args(csv_path), "--json", json_path, "--quiet", *extra_args]
    status, report, stdout, stderr, elapsed, parse_error = run_cli(argv, json_path)
    outcome = Outcome(case, status, report, stdout, stderr, elapsed=elapsed)
    outcome.failures = judge(outcome, parse_error)
    return outcome


def judge(outcome: Outcome, parse_error: str | None = None) -> list[str]:
    """Why ``outcome`` is not a right diagnosis of its run (empty: it is); see the module."""
    case = outcome.case
    truth = case.truth()
    failures = run_failures(outcome.status, outcome.stderr, outcome.report, parse_error)
    report = outcome.report
    if report is None:
        return failures
    named = named_effects(report)
    for name in truth["required"]:  # type: ignore[attr-defined]
        if name not in named:
            failures.append(f"missed {name}")
    one_of = set(truth["one_of"])  # type: ignore[arg-type]
    if one_of and not named & one_of:
        failures.append(f"missed {' or '.join(sorted(one_of))}")
    wrong = named - set(truth["allowed"])  # type: ignore[arg-type]
    if wrong:
        failures.append(f"named absent {','.join(sorted(wrong))}")
    if truth["no_resonance"]:
        detail = report.get("verdict_detail") or {}
        said = " ".join(str(detail.get(k, "")) for k in ("reason", "residual"))
        if "resonance" in said:
            failures.append("the hum called a resonance")
    if truth["expect_warning"]:
        warns = " ".join(str(w) for w in report.get("warnings", []))
        if str(truth["expect_warning"]) not in warns:
            failures.append(f"no warning that the log was {truth['expect_warning']}")
    pos = report.get("position") or {}
    before, after = pos.get("rms_before"), pos.get("rms_after")
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (before, after)):
        failures.append(f"position rms {before} -> {after}")
    elif after > max(0.5 * before, 1.5 * case.floor):
        failures.append(f"rms {before:.3g} -> {after:.3g} (x{before / max(after, 1e-300):.2f}), "
                        f"floor {case.floor:.3g}")
    return failures
