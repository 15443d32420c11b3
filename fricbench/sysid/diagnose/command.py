"""Command line of ``fricbench diagnose``.

``fricbench diagnose DATA.csv [--validate OTHER.csv] [--json OUT.json] [--report DIR]``

Wire it into a CLI with :func:`add_parser` and :func:`run`; :func:`main` runs it alone
(``python -m fricbench.sysid.diagnose.command DATA.csv``). Bad input (file or option) gives a
one-line error and exit status 2, a diagnosis that fails or finds no finite model exit status
1, never a traceback.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import re
import shlex
import sys
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from fricbench.units import PositionUnit, position_unit

if TYPE_CHECKING:
    from fricbench.sysid.io import RunData

__all__ = ["add_parser", "run", "main", "EXIT_OK", "EXIT_FAILED", "EXIT_BAD_INPUT"]

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2


def _configure(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("data", help="CSV run: time, reference, measured position "
                        "[, effort]")
    parser.add_argument("--validate", metavar="OTHER.csv",
                        help="another run of the same axis: evaluate the final model on it")
    parser.add_argument("--json", metavar="OUT.json", help="write the JSON report here")
    parser.add_argument("--report", metavar="DIR",
                        help="write report.json and the residual plots into this directory")
    cols = parser.add_argument_group(
        "columns", "a column is a header name or, when no column has that name, a 0-based "
                   "index (0 is the first column); ',', ';' or tab separated, decimal point")
    cols.add_argument("--time", default=None, help="time column, s (default: t)")
    cols.add_argument("--sample-time", type=float, default=None, metavar="SECONDS",
                      help="for a log without a time column: its sample time; row k is at "
                           "t = k * SECONDS (not with a time column)")
    cols.add_argument("--reference", default="x_ref",
                      help="reference position column (default: x_ref)")
    cols.add_argument("--position", default="x",
                      help="measured position column (default: x)")
    cols.add_argument("--load-position", default=None, metavar="COL",
                      help="a second, load-side position column (a linear scale, or the "
                           "load's encoder behind a coupling), in --position-unit; --position "
                           "is then the motor encoder, and the compliance effect is fitted to "
                           "both")
    cols.add_argument("--position-unit", default="m", choices=("m", "mm", "um", "rad", "deg"),
                      help="unit of the position columns: m, mm, um (linear axis) or rad, deg "
                           "(rotary axis); converted to m or rad inside, figures printed in "
                           "um, mrad or deg (default: m)")
    cols.add_argument("--effort", default=None,
                      help="effort column (force, current or voltage); default: u when the "
                           "file has it")
    cols.add_argument("--no-effort", action="store_true",
                      help="ignore any effort column (diagnose from the position only)")
    cols.add_argument("--effort-unit", default=None,
                      help="unit of the effort, used to label force parameters (default: N, "
                           "with a warning in the report: a logged effort is often a current, "
                           "a voltage or a raw controller output)")
    tune = parser.add_argument_group("analysis")
    tune.add_argument("--quantum", type=float, default=None,
                      help="the position sensor's step, in --position-unit (default: detected "
                           "from the data; rounded exports tolerated)")
    tune.add_argument("--max-effects", type=int, default=8,
                      help="most effects to add (default: 8)")
    tune.add_argument("--try", dest="try_effects", action="append", default=[],
                      metavar="EFFECT",
                      help="also try this effect, one the search leaves out unless asked (the "
                           "friction profiles friction_profile_3, _5, _9: a friction level of "
                           "any shape along the stroke); repeat for more")
    tune.add_argument("--filter-hz", type=float, default=None,
                      help="derivative filter cut-off of the inverse dynamics, Hz "
                           "(default: a tenth of the sampling rate)")
    tune.add_argument("--decimate", type=int, default=None,
                      help="decimation of the inverse dynamics (default: 10)")
    tune.add_argument("--tf", action="store_true",
                      help="also fit a black-box transfer function and report its position "
                           "error, for comparison (slow on long runs)")
    ol = parser.add_argument_group("open loop", "the effort is the input, the position the "
                                    "output: no reference column needed")
    ol.add_argument("--open-loop", action="store_true",
                    help="simulate the position free-run from the effort (needs an effort "
                         "column; any reference column is ignored)")
    ol.add_argument("--init-samples", type=int, default=20, metavar="N",
                    help="open loop: samples of each free run used for its initial state "
                         "(default: 20)")
    twin = parser.add_argument_group(
        "twin", "write the identified model as a Gymnasium env spec (closed loop only)")
    twin.add_argument("--env-out", metavar="FILE.toml",
                      help="write the twin's env spec here (put its folder on "
                           "FRICBENCH_ENV_PATH, then gym.make(ID) or fricbench bench --envs ID)")
    twin.add_argument("--env-id", metavar="ID",
                      help="the twin's env id, namespace/Name-vN, in a namespace of your "
                           "own such as local/MyMill-v0; an id already registered is refused "
                           "(default: from the file name, twin.toml -> fricbench/Twin-v0)")
    twin.add_argument("--env-description", metavar="TEXT",
                      help="the twin's description (default: the run it comes from, the effects "
                           "found and what it does not model)")
    twin.add_argument("--effort-gain", type=float, default=None, metavar="N_PER_UNIT",
                      help="newtons per unit of the effort (the drive's gain), to write the "
                           "twin in SI; required when --effort-unit is not N")
    twin.add_argument("--effort-limit", type=float, default=None, metavar="LIMIT",
                      help="the drive's limit, in the effort's unit (default: the clip level "
                           "seen in the run, else 10 x its largest effort)")
    twin.add_argument("--env-mass", type=float, default=1.0, metavar="KG",
                      help="a run without an effort is modelled per unit mass: the twin's "
                           "moving mass, kg (default: 1)")
    parser.add_argument("--force", action="store_true",
                        help="overwrite an existing --json or --env-out file (without it, an "
                             "existing file is refused with exit status 2, before any work)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    return parser


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add the ``diagnose`` sub-command to ``subparsers``; its handler is :func:`run`."""
    parser = subparsers.add_parser(
        "diagnose", help="find the effects a linear model of a measured run lacks",
        description="Fit a linear closed-loop model to a run, trace its residual to missing "
                    "physical effects (judged on held-out data), add them and report the "
                    "error before and after.")
    _configure(parser)
    parser.set_defaults(func=run)
    return parser


def _check_options(args: argparse.Namespace, run: RunData | None = None) -> str | None:
    """The first problem with the numeric options, or None; with ``run``, the checks that
    need the data (the Nyquist frequency, the number of samples)."""
    if run is None:
        if args.max_effects < 0:
            return f"--max-effects {args.max_effects}: expected an integer >= 0"
        from fricbench.sysid.diagnose.effects import effect_names

        known = effect_names()
        for name in getattr(args, "try_effects", []):
            if name not in known:
                return (f"--try {name!r}: expected an effect of the library, one of "
                        f"{', '.join(known)}")
        if args.decimate is not None and args.decimate < 1:
            return f"--decimate {args.decimate}: expected an integer >= 1 (1: no decimation)"
        if args.filter_hz is not None and not (math.isfinite(args.filter_hz)
                                               and args.filter_hz > 0.0):
            return f"--filter-hz {args.filter_hz:g}: expected a positive cut-off frequency, Hz"
        if args.quantum is not None and not (math.isfinite(args.quantum) and args.quantum > 0):
            return f"--quantum {args.quantum:g}: expected a positive sensor step"
        if args.sample_time is not None:
            if args.time is not None:
                return (f"--time {args.time} and --sample-time {args.sample_time:g}: give one "
                        "(--sample-time is for a log without a time column)")
            if not (math.isfinite(args.sample_time) and args.sample_time > 0.0):
                return f"--sample-time {args.sample_time:g}: expected a positive time step, s"
        return None
    nyquist = 0.5 / run.ts
    if args.filter_hz is not None and args.filter_hz >= nyquist:
        return (f"--filter-hz {args.filter_hz:g}: expected a cut-off below {nyquist:g} Hz, the "
                f"Nyquist frequency of {run.source} (sampled every {run.ts:g} s)")
    most = run.n_samples // 100
    if args.decimate is not None and args.decimate > most:
        return (f"--decimate {args.decimate}: expected an integer from 1 to {most} for "
                f"{run.source} (at least 100 decimated samples of its {run.n_samples})")
    return None


def _non_finite(obj: object, path: str = "") -> list[str]:
    """Key paths of the NaN, inf and None values in a report, as ``key.sub = value``."""
    if obj is None:
        return [f"{path} = null"]
    if isinstance(obj, dict):
        return [p for k, v in obj.items()
                for p in _non_finite(v, f"{path}.{k}" if path else k)]
    if isinstance(obj, (list, tuple)):
        return [p for i, v in enumerate(obj) for p in _non_finite(v, f"{path}[{i}]")]
    if isinstance(obj, (float, np.floating)) and not math.isfinite(obj):
        return [f"{path} = {float(obj)}"]
    if isinstance(obj, np.ndarray) and obj.dtype.kind == "f" and not np.all(np.isfinite(obj)):
        return [f"{path} = {obj[~np.isfinite(obj)][0]}"]
    return []


def _fmt(value: float | None, scale: float = 1.0, digits: int = 3) -> str:
    return "-" if value is None else f"{value * scale:.{digits}g}"


def run(args: argparse.Namespace) -> int:
    """Run the diagnosis for parsed ``args``; returns the exit status."""
    from fricbench.sysid.io import DataError, load_run

    t_start = time.perf_counter()
    log = (lambda _s: None) if args.quiet else (lambda s: print(s, file=sys.stderr))
    for name in ("json",):
        out = getattr(args, name)
        if out and os.path.dirname(os.path.abspath(out)) and not os.path.isdir(
                os.path.dirname(os.path.abspath(out))):
            print(f"error: --{name} {out}: the directory does not exist", file=sys.stderr)
            return EXIT_BAD_INPUT
    for name in ("json", "env_out"):
        out = getattr(args, name, None)
        if out and os.path.exists(out) and not getattr(args, "force", False):
            print(f"error: --{name.replace('_', '-')} {out}: the file exists; pass --force to "
                  "overwrite it, or give another file name", file=sys.stderr)
            return EXIT_BAD_INPUT
    problem = _check_options(args)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return EXIT_BAD_INPUT
    open_loop = getattr(args, "open_loop", False)
    if open_loop and getattr(args, "try_effects", []):
        print("error: --try: the open-loop search tries its own library of effects; --try "
              "adds to the closed-loop search only", file=sys.stderr)
        return EXIT_BAD_INPUT
    if open_loop and args.no_effort:
        print("error: --open-loop and --no-effort: an open-loop run is driven by its effort "
              "column", file=sys.stderr)
        return EXIT_BAD_INPUT
    problem = _check_twin_options(args)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if open_loop and args.init_samples < 2:
        print(f"error: --init-samples {args.init_samples}: expected an integer >= 2",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    effort = None if args.no_effort else (args.effort or "u")
    required = open_loop or (args.effort is not None and not args.no_effort)
    cols = dict(time=args.time or "t", reference=None if open_loop else args.reference,
                position=args.position,
                effort=effort, effort_required=required, sample_time=args.sample_time,
                position_unit=args.position_unit, load_position=args.load_position)
    try:
        run_data = load_run(args.data, **cols)
        other = load_run(args.validate, **cols) if args.validate else None
    except DataError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    problem = _check_options(args, run_data)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return EXIT_BAD_INPUT
    stated = run_data.units["effort"] if run_data.units.get("effort_stated") else None
    if args.effort_unit is None and stated is not None:
        args.effort_unit = stated  # the file states it (a column 'u [N]')
    elif stated is not None and args.effort_unit != stated:
        print(f"warning: --effort-unit {args.effort_unit}: column {run_data.columns.get('u')!r} "
              f"of {run_data.source} states {stated}; {args.effort_unit} is used",
              file=sys.stderr)
    if args.effort_unit is None:
        args.effort_unit = "N"
        if run_data.u is not None:
            # an assumption the report must carry: labelling a current or a raw controller
            # output in newtons would be a wrong unit at the edge
            run_data = dataclasses.replace(run_data, warnings=(*run_data.warnings, (
                "the effort's unit was not stated (--effort-unit): its forces are labelled N, "
                "but a logged effort is often a current (A), a voltage (V) or a raw "
                "controller output (%, counts)")))
    for w in run_data.warnings + (other.warnings if other is not None else ()):
        print(f"warning: {w}", file=sys.stderr)
    if (getattr(args, "env_out", None) and run_data.u is not None
            and args.effort_unit != "N" and args.effort_gain is None):
        print(f"error: --env-out {args.env_out}: the effort is in {args.effort_unit} "
              f"(--effort-unit); give --effort-gain, the newtons per {args.effort_unit} of the "
              "drive, to write the twin in SI", file=sys.stderr)
        return EXIT_BAD_INPUT
    if open_loop:
        return _run_open_loop(args, run_data, other, log, t_start)
    try:
        from fricbench.sysid.diagnose.diagnosis import diagnose
        from fricbench.sysid.diagnose.effects import default_candidates
        from fricbench.sysid.diagnose.settings import defaults

        settings = dataclasses.replace(defaults(), max_steps=args.max_effects)
        if getattr(args, "try_effects", []):
            tried = default_candidates()
            settings = dataclasses.replace(settings, candidates=tried + tuple(
                dict.fromkeys(e for e in args.try_effects if e not in tried)))
        result = diagnose(run_data, validate=other, force_unit=args.effort_unit,
                          settings=settings,
                          compare_tf=args.tf, cutoff_hz=args.filter_hz, decim=args.decimate,
                          quantum=(None if args.quantum is None else
                                   args.quantum * position_unit(args.position_unit).to_si),
                          log=log)
    except (ValueError, ArithmeticError) as exc:
        # DiagnosisError (no valid model) included: say why, write nothing, exit non-zero
        print(f"error: the diagnosis failed: {str(exc) or type(exc).__name__}", file=sys.stderr)
        return EXIT_FAILED
    report = result.to_dict()
    bad = _non_finite(report)
    if bad:
        more = f" and {len(bad) - 1} more" if len(bad) > 1 else ""
        print(f"error: the diagnosis gave non-finite results ({bad[0]}{more}): no valid model "
              "of this run was found; no report written", file=sys.stderr)
        return EXIT_FAILED
    try:
        if args.json:
            from fricbench.sysid.diagnose.report import write_json

            write_json(args.json, report)
        if args.report:
            from fricbench.sysid.diagnose.report import write_report

            write_report(result, args.report)
    except OSError as exc:
        print(f"error: cannot write the report: {exc}", file=sys.stderr)
        return EXIT_FAILED
    if getattr(args, "env_out", None):
        status = _write_twin(args, result)
        if status != EXIT_OK:
            return status
    _print_summary(report, run_data.n_samples, time.perf_counter() - t_start,
                   position_unit(args.position_unit),
                   frozenset(run_data.warnings + (other.warnings if other is not None else ())))
    return EXIT_OK


def _twin_id(args: argparse.Namespace) -> str:
    """``--env-id``, or ``fricbench/<Stem>-v0`` from the ``--env-out`` file name."""
    if args.env_id is not None:
        return str(args.env_id)
    stem = os.path.splitext(os.path.basename(args.env_out))[0]
    name = "".join(w[:1].upper() + w[1:] for w in re.split(r"[^A-Za-z0-9]+", stem) if w)
    return f"fricbench/{name or 'Twin'}-v0"


def _registered_by(env_id: str, out: str) -> str | None:
    """Where ``env_id`` is registered already (a spec file or Gymnasium), or None; the spec
    file ``out`` itself (a twin written again) does not count."""
    import gymnasium as gym

    from fricbench.gym import env_registry, register_envs

    register_envs()
    if env_id in env_registry.ids():
        path = env_registry.spec(env_id).data.path
        same = os.path.abspath(path) == os.path.abspath(out)
        return None if same else f"by {path}"
    return "in Gymnasium's registry" if env_id in gym.registry else None


def _check_twin_options(args: argparse.Namespace) -> str | None:
    """The first problem with the twin options (``--env-out`` and its companions), or None."""
    from fricbench.gym.specs import ENV_ID_FORM
    from fricbench.sysid.diagnose.twin import check_env_id

    out = getattr(args, "env_out", None)
    if out is None:
        for name in ("env_id", "env_description", "effort_gain", "effort_limit"):
            if getattr(args, name, None) is not None:
                return f"--{name.replace('_', '-')}: only with --env-out FILE.toml"
        return None
    if getattr(args, "open_loop", False):
        return (f"--env-out {out} with --open-loop: an open-loop run identifies the plant but "
                "no controller, and an env needs the loop closed; diagnose a closed-loop run of "
                "the axis (time, reference, position, effort) to write its twin")
    if not out.endswith(".toml"):
        return f"--env-out {out}: expected a file name ending in .toml (an env spec)"
    folder = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(folder):
        return f"--env-out {out}: the directory {folder} does not exist"
    env_id = _twin_id(args)
    try:
        check_env_id(env_id)
    except ValueError:
        return f"--env-id {env_id}: expected {ENV_ID_FORM}"
    taken = _registered_by(env_id, out)
    if taken is not None:
        own = "local/" + env_id.split("/", 1)[1]
        if args.env_id is None:
            return (f"--env-out {out}: the twin's default id {env_id} (from the file name) is "
                    f"already registered ({taken}); give --env-id ID, an id of your own such "
                    f"as {own}")
        return (f"--env-id {env_id}: already registered ({taken}); expected an id of your own, "
                f"such as {own}")
    for name, value in (("--effort-gain", args.effort_gain), ("--effort-limit",
                                                              args.effort_limit),
                        ("--env-mass", args.env_mass)):
        if value is not None and not (math.isfinite(value) and value > 0.0):
            return f"{name} {value:g}: expected a positive number"
    return None


def _write_twin(args: argparse.Namespace, result: object) -> int:
    """Write ``--env-out`` from a closed-loop diagnosis and check that it loads."""
    from fricbench.gym.specs import EnvSpecError, load_spec
    from fricbench.sysid.diagnose.twin import TwinError, twin_spec, write_twin

    env_id = _twin_id(args)
    try:
        spec, comments = twin_spec(result, env_id, effort_gain=args.effort_gain,
                                   mass=args.env_mass, effort_limit=args.effort_limit,
                                   description=args.env_description)
    except (TwinError, ValueError) as exc:
        print(f"error: --env-out {args.env_out}: no twin written: {exc}", file=sys.stderr)
        return EXIT_FAILED
    comments.insert(2, "Command: fricbench " + " ".join(
        shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:2] == ["diagnose"] else
        "Command: fricbench diagnose ... --env-out")
    try:
        write_twin(args.env_out, spec, comments)
    except OSError as exc:
        print(f"error: --env-out {args.env_out}: cannot write: {exc}", file=sys.stderr)
        return EXIT_FAILED
    try:
        load_spec(args.env_out)
    except EnvSpecError as exc:
        os.remove(args.env_out)
        print(f"error: --env-out {args.env_out}: the written spec does not load ({exc}); "
              "removed", file=sys.stderr)
        return EXIT_FAILED
    folder = os.path.dirname(os.path.abspath(args.env_out))
    print(f"wrote {args.env_out}: env {env_id} (put {folder} on FRICBENCH_ENV_PATH to "
          "gym.make it)")
    return EXIT_OK


def _run_open_loop(args: argparse.Namespace, run_data: RunData, other: RunData | None,
                   log: Callable[[str], None], t_start: float) -> int:
    """``--open-loop``: the free-run diagnosis of :mod:`fricbench.sysid.diagnose.open_loop`."""
    from fricbench.sysid.diagnose.open_loop import diagnose_open_loop, print_open_loop_summary

    assert run_data.u is not None  # the effort column is required in open loop
    val = None
    if other is not None:
        assert other.u is not None
        val = (other.t, other.u, other.x)
    try:
        report = diagnose_open_loop(run_data.t, run_data.u, run_data.x, validate=val,
                                    n_init=args.init_samples, force_unit=args.effort_unit,
                                    max_effects=args.max_effects, log=log,
                                    position_unit=(run_data.logged_unit.name,
                                                   run_data.logged_unit.to_si))
    except (ValueError, ArithmeticError) as exc:
        print(f"error: the open-loop diagnosis failed: {str(exc) or type(exc).__name__}",
              file=sys.stderr)
        return EXIT_FAILED
    report["source"] = run_data.source
    if run_data.x_load is not None:
        note = ("--load-position: the open-loop fit uses the motor position only; the load "
                "position is not used open loop yet")
        print(f"warning: {note}", file=sys.stderr)
        warnings = report.get("warnings")
        if isinstance(warnings, list):
            warnings.append(note)
    bad = _non_finite(report)
    if bad:
        print(f"error: the open-loop diagnosis gave non-finite results ({bad[0]}): no report "
              "written", file=sys.stderr)
        return EXIT_FAILED
    if args.json:
        from fricbench.sysid.diagnose.report import write_json

        try:
            write_json(args.json, report)
        except OSError as exc:
            print(f"error: cannot write the report: {exc}", file=sys.stderr)
            return EXIT_FAILED
    print_open_loop_summary(report, time.perf_counter() - t_start)
    return EXIT_OK


def _sliding(effort: dict) -> str:
    """The effort error over the sliding samples, when the report has it (at rest the effort
    is the integrator's hold against stiction, which the error over every sample counts)."""
    if "relerr_sliding_before_pct" not in effort:
        return ""
    return (f" (while sliding {effort['relerr_sliding_before_pct']:.3f} -> "
            f"{effort['relerr_sliding_after_pct']:.3f} %)")


def _print_summary(report: dict, n_samples: int, elapsed: float,
                   unit: PositionUnit | None = None, printed: frozenset[str] = frozenset()
                   ) -> None:
    unit = unit or position_unit("m")
    sfx, k, lab = unit.si, unit.per_si, unit.display
    effects = report["effects"]
    for w in report["warnings"]:
        if w not in printed:
            print(f"warning: {w}", file=sys.stderr)
    v = report["verdict_detail"]
    print(f"verdict: {v['verdict']}: {v['reason']}; residual: {v['residual']}")
    print(f"effects found: {', '.join(effects) if effects else 'none'}")
    sds = report.get("parameter_sd", {})
    for name, values in report.get("parameters", {}).items():
        sd = sds.get(name, {})
        # each value with its standard deviation (the JSON's parameter_sd) where there is one
        print(f"  {name}: " + ", ".join(
            f"{k}={v:.4g}" + (f" +- {sd[k]:.2g}" if k in sd else "") for k, v in values.items()))
    if report["steps"]:
        print("search steps (each effect's values when it was added, before later refits):")
    for step in report["steps"]:
        params = ", ".join(f"{k}={v:.4g}" for k, v in step["parameters"].items())
        m = step["metrics"]
        extra = (f", effort {m['effort_relerr_pct']:.3f} %" if "effort_relerr_pct" in m
                 else "")
        print(f"  {step['step']}. {step['effect']}: {params}  "
              f"(position rms {m[f'position_rms_{sfx}'] * k:.4g} {lab}{extra})")
    pos = report["position"]
    nf = report["noise_floor"]
    q_shown = (f"{nf[f'quantum_{sfx}'] * k:.3g} {lab}" if nf[f"quantum_{sfx}"] > 0.0
               else "none found")
    print(f"position rms  {pos['rms_before'] * k:.4g} -> {pos['rms_after'] * k:.4g} {lab}, "
          f"max {pos['max_before'] * k:.4g} -> {pos['max_after'] * k:.4g} {lab} "
          f"(noise floor {nf[f'prediction_floor_{sfx}'] * k:.3g} {lab}, sensor quantum "
          f"{q_shown})")
    if "effort" in report:
        e = report["effort"]
        print(f"effort relerr {e['relerr_before_pct']:.3f} -> {e['relerr_after_pct']:.3f} %"
              + _sliding(e))
    if "validation" in report:
        v = report["validation"]
        vp = v["position"]
        print(f"validation ({os.path.basename(v['source'])}): position rms "
              f"{vp['rms_before'] * k:.4g} -> {vp['rms_after'] * k:.4g} {lab}"
              + (f", effort relerr {v['effort']['relerr_before_pct']:.3f} -> "
                 f"{v['effort']['relerr_after_pct']:.3f} %{_sliding(v['effort'])}"
                 if "effort" in v else ""))
    print(f"stop: {report['stop_reason']}")
    print(f"elapsed: {elapsed:.1f} s for {n_samples} samples")


def main(argv: Sequence[str] | None = None) -> int:
    """Stand-alone entry point (``python -m fricbench.sysid.diagnose.command``)."""
    parser = _configure(argparse.ArgumentParser(prog="fricbench diagnose"))
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
