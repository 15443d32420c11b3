"""The ``fricbench`` command line: parses arguments, calls library functions, prints.

Subcommands: ``list``, ``simulate``, ``perf``, ``bench``, and those contributed by the
bench (``reproduce``), compensator (``train``) and diagnosis (``diagnose``) packages.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from fricbench.bench.runner import EpisodeRecord
    from fricbench.registry import Registry

__all__ = ["main"]

# subcommand modules exposing add_parser(subparsers) and run(args) -> int
_PLUGGED = ("fricbench.bench.reproduce_command", "fricbench.compensators.command",
            "fricbench.sysid.diagnose.command")


def _first_paragraph(doc: str | None) -> str:
    """The first paragraph of a docstring on one line, without reST double backquotes."""
    para = (doc or "").strip().split("\n\n")[0]
    return " ".join(para.split()).replace("``", "")


def _package_of(obj: object) -> str:
    """The distribution that provides ``obj`` (an entry-point string or a callable)."""
    module = obj.split(":")[0] if isinstance(obj, str) else getattr(obj, "__module__", "")
    top = (module or "").split(".")[0]
    if top == "fricbench" or not top:
        return "fricbench"
    return importlib.metadata.packages_distributions().get(top, [top])[0]


def _registry_rows(registry: Registry[Any]) -> list[tuple[str, str, str]]:
    """``(id, package, description)`` of every registered id; an empty description is the
    first paragraph of the factory's docstring."""
    rows = []
    for i in registry.ids():
        entry = registry.spec(i)
        desc = entry.description or _first_paragraph(entry.load().__doc__)
        rows.append((i, _package_of(entry.entry_point), desc.replace("``", "")))
    return rows


def _env_rows() -> list[tuple[str, str, str]]:
    """``(id, source, description)`` of every env: ``fricbench`` or the spec's file (a user's
    or a plug-in's)."""
    from fricbench.gym import env_registry, register_envs
    from fricbench.gym.specs import _shipped_files

    register_envs()  # the files added to FRICBENCH_ENV_PATH since the import
    shipped = {str(f) for f in _shipped_files()}
    rows = []
    for i in env_registry.ids():
        spec = env_registry.spec(i).data
        rows.append((i, "fricbench" if spec.path in shipped else spec.path, spec.description))
    return rows


def _cmd_list(args: argparse.Namespace) -> int:
    from fricbench.compensators import compensator_registry
    from fricbench.friction import friction_registry
    from fricbench.predictors import predictor_registry
    from fricbench.trajectories import trajectory_registry

    sections = [("friction models", _registry_rows(friction_registry)),
                ("trajectories", _registry_rows(trajectory_registry)),
                ("environments", _env_rows()),
                ("predictors", _registry_rows(predictor_registry)),
                ("compensators", _registry_rows(compensator_registry))]
    for title, rows in sections:
        print(f"{title}:")
        width = max((len(i) for i, _, _ in rows), default=0)
        pkg_width = max((len(p) for _, p, _ in rows), default=0)
        for i, package, desc in rows:
            print(f"  {i:<{width}}  {package:<{pkg_width}}  {desc}".rstrip())
    if not args.check:
        return 0
    from fricbench.gym import check_specs, spec_files

    problems = [(exc.path, p) for exc in check_specs() for p in exc.problems]
    print(f"env specs: {len(spec_files())} files checked, {len(problems)} problem"
          f"{'' if len(problems) == 1 else 's'}")
    for path, problem in problems:
        print(f"  {path}: {problem}")
    return 1 if problems else 0


def _refuse_existing(args: argparse.Namespace, options: tuple[str, ...]) -> None:
    """Raise when an output file of ``options`` exists and ``--force`` was not given."""
    if args.force:
        return
    for name in options:
        out = getattr(args, name)
        if out and Path(out).exists():
            raise ValueError(f"--{name} {out}: the file exists; pass --force to overwrite it, "
                             "or give another file name")


def _cmd_simulate(args: argparse.Namespace) -> int:
    import numpy as np

    from fricbench.axis import simulate
    from fricbench.axis.export import plot_ballbar, plot_run, write_csv
    from fricbench.gym import get_spec
    from fricbench.trajectories import make_trajectory

    _refuse_existing(args, ("csv", "plot", "polar"))
    spec = get_spec(args.env)
    axis = spec.axis
    measured = None
    if args.reference_csv:
        if args.trajectory is not None:
            raise ValueError(f"--trajectory {args.trajectory} and --reference-csv "
                             f"{args.reference_csv}: give one reference")
        for opt in ("time", "reference", "position"):
            if getattr(args, opt) is not None and not getattr(args, opt).strip():
                raise ValueError(f"--{opt} {getattr(args, opt)!r}: expected a column name or "
                                 "a 0-based index")
        ref, measured = _reference_from_csv(args, axis.controller.ts)
        args.trajectory = f"the reference of {args.reference_csv}"
    else:
        for opt in ("time", "reference", "position"):
            if getattr(args, opt) is not None:
                raise ValueError(f"--{opt} {getattr(args, opt)}: only with --reference-csv")
        # the env's own trajectories with the parameters its spec gives them (EMPS-v0's stroke
        # fits its rail); by default its first one (the circle env draws a circle)
        choices = spec.task.trajectories
        args.trajectory = args.trajectory or (choices[0].id if choices else "m_serial")
        params = next((c.params for c in choices if c.id == args.trajectory), {})
        ref = make_trajectory(args.trajectory, ts=axis.controller.ts, **params)
    if args.polar and ref.name != "circle":
        raise ValueError(f"--polar {args.polar}: the ballbar plot is drawn for the circle "
                         f"trajectory, not {args.trajectory!r} (use --trajectory circle)")
    x0 = v0 = None
    if measured is not None:
        # the run's own start: its first position, and the slope of a quadratic through its
        # first 10 samples (the reference's velocity may differ: a lagging axis)
        n0 = min(10, measured.shape[0])
        tt = np.arange(n0) * axis.controller.ts
        slope = np.polyfit(tt, measured[:n0], min(2, n0 - 1))[-2] if n0 > 1 else 0.0
        x0, v0 = float(measured[0]), float(slope)
    res = simulate(axis, ref, seed=args.seed, x0=x0, v0=v0)
    if args.csv:
        cols = write_csv(res, args.csv)
        print(f"wrote {args.csv}: {res.t.size} rows, columns {', '.join(cols)} (t in s, "
              "positions in m)")
    if args.plot:
        plot_run(res, f"{args.env} on {args.trajectory}", args.plot)
        print(f"wrote {args.plot}")
    if args.polar:
        k = plot_ballbar(res, f"{args.env} on {args.trajectory}: ballbar (radial error)",
                         args.polar)
        print(f"wrote {args.polar} (radial error magnified x{k:g})")
    err = np.atleast_2d(res.error) * 1e6
    print(f"{args.env} / {args.trajectory}: max |e| = {np.abs(err).max():.2f} um, "
          f"rms = {np.sqrt((err**2).mean()):.2f} um over {res.t[-1]:.2f} s")
    if measured is not None:
        dev = (res.x - measured) * 1e6
        print(f"replay against the measured position ({args.position}): rms "
              f"{np.sqrt(np.mean(dev**2)):.4g} um, max {np.max(np.abs(dev)):.4g} um")
    return 0


REPLAY_TS_TOLERANCE = 1.0e-3
"""Relative difference between a replayed log's sample time and the env's that is accepted."""


def _reference_from_csv(args: argparse.Namespace, ts: float) -> tuple[Any, Any]:
    """The reference of ``--reference-csv`` (velocity and acceleration by central
    differences, as the diagnosis takes them) and the measured position when ``--position``
    names one."""
    import numpy as np

    from fricbench.sysid.io import DataError, load_run
    from fricbench.trajectories import Reference

    ref_col = args.reference or "x_ref"
    try:
        if args.position:
            run = load_run(args.reference_csv, time=args.time or "t", reference=ref_col,
                           position=args.position, effort=None)
        else:  # the reference alone, read as a run without one (its x_ref is the column)
            run = load_run(args.reference_csv, time=args.time or "t", reference=None,
                           position=ref_col, effort=None)
    except DataError as exc:
        raise ValueError(str(exc)) from None
    if abs(run.ts - ts) > REPLAY_TS_TOLERANCE * ts:
        raise ValueError(f"--reference-csv {args.reference_csv}: sampled every {run.ts:g} s but "
                         f"{args.env} runs at ts={ts:g} s: expected the env's sample time "
                         f"(within {REPLAY_TS_TOLERANCE:.0e} of it)")
    # sample k is replayed at k ts (a log's clock jitter is not the reference's)
    n = run.n_samples
    vr = np.gradient(run.x_ref, ts)
    ar = np.gradient(vr, ts)
    ref = Reference(t=np.arange(n) * ts, x=np.asarray(run.x_ref, dtype=float), v=vr, a=ar,
                    name="csv", params={"file": str(args.reference_csv)})
    return ref, (np.asarray(run.x, dtype=float) if args.position else None)


def _cmd_perf(args: argparse.Namespace) -> int:
    from fricbench._atomic import atomic_write
    from fricbench.bench.perf import format_report, measure_performance

    try:
        result = measure_performance(quick=args.quick)
    except RuntimeError as exc:  # a refused measurement: say why, no traceback
        print(f"fricbench perf: error: {exc}", file=sys.stderr)
        return 1
    print(format_report(result))
    if args.json:
        atomic_write(args.json, json.dumps(result, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


# generated files (the tables a bench writes): not what makes a commit "+dirty", so that the
# second command of `make bench` names the commit as the first one does
_GENERATED = tuple(f":(top,exclude,glob)leaderboards/**/*.{ext}" for ext in ("csv", "md", "png"))


def _git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, check=True, cwd=Path(__file__).resolve().parent)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--",
                                ":(top)", *_GENERATED],
                               capture_output=True, text=True, check=True,
                               cwd=Path(__file__).resolve().parent).stdout.strip()
        return out.stdout.strip() + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


# run_benchmark parameter -> the bench option that sets it
_BENCH_OPTIONS = {"env_ids": "--envs", "comp_ids": "--compensators",
                  "trajectories": "--trajectories", "seeds": "--seeds",
                  "comp_kwargs": "--compensator-kwargs", "comp_config": "--compensator-config"}


def _toml_value(text: str) -> Any:
    """``text`` read as a TOML value (``0.3``, ``true``, ``"a b"``, ``[1, 2]``); text that is
    not one TOML value (``runs/sac.json``, ``sac``) is that string."""
    import tomllib

    try:
        table = tomllib.loads(f"v = {text}")
    except tomllib.TOMLDecodeError:
        return text
    return table["v"] if list(table) == ["v"] else text


def _compensator_kwargs(args: argparse.Namespace) -> tuple[dict[str, dict[str, Any]],
                                                             set[str], set[str]]:
    """The compensator settings of ``--compensator-config`` then ``--compensator-kwargs`` (which
    win key by key), and where each came from: the ``id`` and ``id:key`` strings of each
    option."""
    from fricbench.bench.runner import BenchConfigError, read_compensator_config

    settings: dict[str, dict[str, Any]] = {}
    from_file: set[str] = set()
    if args.compensator_config:
        settings = read_compensator_config(args.compensator_config)
        from_file = {*settings, *(f"{c}:{k}" for c, kw in settings.items() for k in kw)}
    from_cli: set[str] = set()
    for item in args.compensator_kwargs:
        target, eq, value = item.partition("=")
        cid, colon, key = target.rpartition(":")  # ids may hold a colon: precomp:tf:gain=0.5
        if not (eq and colon and cid and key.strip()):
            raise BenchConfigError("comp_kwargs", item,
                                   "expected ID:KEY=VALUE, such as ilc:gain=0.3")
        settings.setdefault(cid, {})[key.strip()] = _toml_value(value.strip())
        from_cli |= {cid, f"{cid}:{key.strip()}"}
    return settings, from_cli, from_file


def _bench_option(exc: Any, args: argparse.Namespace, from_cli: set[str],
                  from_file: set[str]) -> str:
    """The option a :class:`BenchConfigError` is about (with the file, for the config)."""
    if exc.parameter == "comp_config":
        return _BENCH_OPTIONS["comp_config"]
    if exc.parameter != "comp_kwargs":
        return _BENCH_OPTIONS[exc.parameter]
    where = [opt for opt, seen in (("--compensator-kwargs", from_cli),
                                   (f"--compensator-config {args.compensator_config}", from_file))
             if exc.value in seen]
    return " and ".join(where) or "--compensator-kwargs"


def _cmd_bench(args: argparse.Namespace) -> int:
    from fricbench.bench.leaderboard import write_leaderboards
    from fricbench.bench.runner import BenchConfigError, plan_benchmark, run_benchmark
    from fricbench.compensators import compensator_registry
    from fricbench.gym import env_ids, get_spec

    t0 = getattr(args, "started", None) or time.perf_counter()
    if args.jobs != -1 and args.jobs < 1:
        print(f"fricbench bench: error: --jobs {args.jobs}: expected a positive number of "
              "processes, or -1 for one per core", file=sys.stderr)
        return 2
    envs = args.envs or env_ids(benchmark_only=True)
    comps = args.compensators or compensator_registry.ids()
    from_cli: set[str] = set()
    from_file: set[str] = set()
    try:  # every id, seed and setting, before anything is fitted
        comp_kwargs, from_cli, from_file = _compensator_kwargs(args)
        tasks = plan_benchmark(envs, comps, args.seeds, args.trajectories, comp_kwargs)
    except BenchConfigError as exc:
        print(f"fricbench bench: error: {_bench_option(exc, args, from_cli, from_file)} "
              f"{exc.value}: {exc.problem}", file=sys.stderr)
        return 2
    records = []
    work: dict[str, float] = {}
    interrupted = False
    broken: Exception | None = None
    try:
        for rec in run_benchmark(envs, comps, args.seeds, args.trajectories,
                                 backend=args.backend, n_jobs=args.jobs, address=args.address,
                                 comp_kwargs=comp_kwargs, nominal=args.nominal,
                                 work=work):
            records.append(rec)
    except KeyboardInterrupt:
        interrupted = True
    except Exception as exc:  # noqa: BLE001 - a backend that breaks (a lost cluster): keep the
        broken = exc          # finished runs, as Ctrl-C does
    command = "fricbench " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["bench"] else \
        "fricbench bench"
    descriptions = {e: (get_spec(e).description, get_spec(e).fit_on) for e in envs}
    if args.out is None:
        args.out = "leaderboards/nominal" if args.nominal else "leaderboards"
    # an interrupted or broken run merges: its missing cells keep their earlier rows
    fresh = args.fresh and not interrupted and broken is None
    paths = write_leaderboards(records, args.out, command, _git_commit(), descriptions, fresh)
    failed = [r for r in records if r.status != "ok"]
    for p in paths:
        if p.suffix == ".md":
            print(p.read_text(encoding="utf-8").split("## Error traces")[0])
    _print_act_times(records, args.out)
    print(_wall_time_line(len(records), len(failed), time.perf_counter() - t0, args.jobs
                          if args.backend == "joblib" else None, work, len(paths), args.out))
    if interrupted or broken is not None:
        done = {(r.env, r.compensator, r.trajectory, r.seed) for r in records}
        missing = [t for t in tasks if (t.env, t.compensator, t.trajectory, t.seed) not in done]
        why = "interrupted" if broken is None else \
            f"error: the run stopped ({type(broken).__name__}: {broken})"
        print(f"fricbench bench: {why}: {len(records)} of {len(tasks)} runs finished"
              f"{' and written' if records else '; nothing written'}; "
              f"{len(missing)} not run:", file=sys.stderr)
        _print_cells([(t.env, t.compensator, t.trajectory, t.seed) for t in missing])
        return 130 if broken is None else 1
    if failed:
        print(f"fricbench bench: {len(failed)} of {len(records)} runs failed (a failure never "
              f"replaces a good row; each is in <env>.failures.csv):", file=sys.stderr)
        _print_cells([(r.env, r.compensator, r.trajectory, r.seed, r.reason) for r in failed])
        return 1
    return 0


def _wall_time_line(n_runs: int, n_failed: int, wall: float, jobs: int | None,
                    work: dict[str, float], n_files: int, out: str) -> str:
    """The bench's last line: its wall time from the command's start, then the CPU seconds of
    its fits and runs per env (fits under their training env, summed over the processes: where
    the time went, apart from what else the machine runs)."""
    on = f" on {jobs} job{'' if jobs == 1 else 's'}" if jobs is not None else ""
    per_env = ", ".join(f"{e.split('/', 1)[-1]} {s:.0f}" for e, s in
                        sorted(work.items(), key=lambda kv: -kv[1]))
    spent = (f" (fits and runs, CPU s: {sum(work.values()):.0f}; per env: {per_env})"
             if per_env else "")
    return (f"bench wall time: {wall:.0f} s{on}, {n_runs} runs ({n_failed} failed){spent}; "
            f"wrote {n_files} files under {out}/")


def _print_cells(cells: list[tuple[object, ...]], limit: int = 12) -> None:
    """Print ``(env, compensator, trajectory, seed[, reason])`` to stderr, seeds grouped."""
    groups: dict[tuple[object, ...], list[str]] = {}
    for env, comp, traj, seed, *reason in cells:
        groups.setdefault((env, comp, traj, *reason), []).append(str(seed))
    for i, (key, seeds) in enumerate(groups.items()):
        if i == limit:
            print(f"  ... and {len(groups) - limit} more", file=sys.stderr)
            break
        env, comp, traj, *reason = key
        why = f": {reason[0]}" if reason else ""
        print(f"  {env} {comp} {traj} seed{'s' if len(seeds) > 1 else ''} "
              f"{', '.join(seeds)}{why}", file=sys.stderr)


def _print_act_times(records: list[EpisodeRecord], out: str) -> None:
    """Median per-step ``act`` time per compensator (machine-dependent, kept out of tables)."""
    times: dict[str, list[float]] = {}
    for r in records:
        if r.status == "ok":
            times.setdefault(r.compensator, []).append(r.step_time * 1e6)
    if times:
        med = ", ".join(f"{c} {statistics.median(v):.1f}" for c, v in sorted(times.items()))
        print(f"act time (us/step, median of this run; in {out}/timings/, not in the tables): "
              f"{med}")


def _version() -> str:
    """The installed distribution's version (``fricbench.__version__`` when not installed)."""
    try:
        return importlib.metadata.version("fricbench")
    except importlib.metadata.PackageNotFoundError:
        from fricbench import __version__

        return __version__


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand."""
    parser = argparse.ArgumentParser(
        prog="fricbench",
        description="Servo-friction compensation benchmark: simulate CNC feed axes with "
                    "friction, compare compensators, train RL policies, diagnose measured runs.",
        epilog="Run 'fricbench <command> --help' for the options of a command.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser(
        "list", help="list the available models, trajectories, envs, predictors, compensators",
        description="List every friction model, trajectory, environment, predictor and "
                    "compensator id with its description and the package it comes from.")
    p.add_argument("--check", action="store_true",
                   help="also validate every env spec file (shipped and FRICBENCH_ENV_PATH); "
                        "report each problem and exit 1 if there is one")
    p.set_defaults(func=_cmd_list)

    from fricbench.gym import env_ids
    from fricbench.trajectories import trajectory_registry

    p = sub.add_parser(
        "simulate", help="simulate an env's axis on a trajectory, without compensation",
        description="Simulate the axis of an environment following a reference trajectory "
                    "(no compensation) and print the tracking error.")
    p.add_argument("--env", default="fricbench/PaperAxis-v0",
                   help=f"environment id, one of: {', '.join(env_ids())} "
                        "(default: %(default)s)")
    p.add_argument("--trajectory", default=None,
                   help=f"trajectory id, one of: {', '.join(trajectory_registry.ids())} "
                        "(circle needs a 2-axis env; default: the env's first, e.g. "
                        "m_serial on PaperAxis-v0, circle on CircleContouring-v0; one of the "
                        "env's own is drawn with the parameters its spec gives it)")
    p.add_argument("--reference-csv", metavar="RUN.csv",
                   help="replay the reference of a logged run instead of a trajectory (m, at "
                        "the env's sample time): to check a twin against its measurement")
    p.add_argument("--time", default=None, metavar="COL",
                   help="with --reference-csv: time column, s (default: t)")
    p.add_argument("--reference", default=None, metavar="COL",
                   help="with --reference-csv: reference position column, m (default: x_ref)")
    p.add_argument("--position", default=None, metavar="COL",
                   help="with --reference-csv: the measured position column, m: the replay "
                        "starts there and prints its error against it")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the measurement noise, where the env has any "
                        "(default: %(default)s)")
    p.add_argument("--csv", metavar="FILE.csv",
                   help="write the run as columns t, x_ref, x, 'u [N]' (s, m, m, N; the "
                        "effort's unit in its name, where diagnose reads it)")
    p.add_argument("--plot", metavar="FILE.png",
                   help="write a PNG of reference, position and error")
    p.add_argument("--polar", metavar="FILE.png",
                   help="circle only: write the ballbar picture, a polar plot of the radius "
                        "with the radial error magnified (scale written on the plot)")
    p.add_argument("--force", action="store_true",
                   help="overwrite existing --csv, --plot and --polar files (without it, an "
                        "existing file is refused with exit status 2, before simulating)")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser(
        "perf", help="measure simulation speed on this machine",
        description="Measure simulation speed (steps or samples per second) of the env, the "
                    "vector env (beside the bare kernel run over the same samples) and "
                    "simulate, beside Gymnasium's Pendulum-v1 and python-control measured in "
                    "the same run for comparison, and PPO "
                    "training speed on the vector env beside stable-baselines3's DummyVecEnv.")
    p.add_argument("--json", metavar="FILE.json", help="write the figures to this JSON file")
    p.add_argument("--quick", action="store_true", help="shorter runs (noisier)")
    p.set_defaults(func=_cmd_perf)

    p = sub.add_parser(
        "bench", help="run compensators on the benchmark envs; write leaderboards",
        description="Run compensators on the benchmark envs and merge the runs into the "
                    "leaderboards. Exit 0 when every run succeeded, 1 when a run failed (the "
                    "tables keep the last good rows; failures in <env>.failures.csv) or the "
                    "backend broke off (finished runs written), 2 on a "
                    "bad option (checked before any fitting), 130 on Ctrl-C (finished runs "
                    "written).")
    p.add_argument("--envs", nargs="+", help="env ids (default: every benchmark env)")
    p.add_argument("--compensators", nargs="+", help="compensator ids (default: all)")
    p.add_argument("--compensator-kwargs", action="append", default=[], metavar="ID:KEY=VALUE",
                   help="a constructor keyword of one compensator, such as ilc:gain=0.3 or "
                        "rl-sac:policy=runs/sac/policy.json; VALUE is read as TOML (a number, "
                        "true or false, a quoted string, an array), other text as a string; "
                        "repeat the option for more; wins over --compensator-config")
    p.add_argument("--compensator-config", metavar="FILE.toml",
                   help="constructor keywords per compensator: a TOML table per id, such as "
                        "'[ilc]' then 'gain = 0.3' (quote ids with a colon: [\"precomp:tf\"]). "
                        "The settings of each run are in the tables and CSV")
    p.add_argument("--trajectories", nargs="+", help="override each env's trajectory set")
    p.add_argument("--seeds", nargs="+", type=int, default=list(range(10)),
                   help="seeds, each a machine of its own: a plant drawn around the env's "
                        "nominal axis, its measurement noise and its own fits (default: 0 to "
                        "9)")
    p.add_argument("--nominal", action="store_true",
                   help="run the env's nominal, noise-free axis on every seed, each "
                        "compensator fitted once (the axis of 'fricbench reproduce' and the "
                        "docs' figures; the seeds are copies); writes to leaderboards/nominal "
                        "unless --out is given")
    p.add_argument("--fresh", action="store_true",
                   help="write the tables of the envs run from this run's rows alone, dropping "
                        "their earlier rows and seeds (what 'make bench' does); without it a "
                        "run merges into them. An interrupted run merges either way")
    p.add_argument("--backend", choices=("joblib", "ray"), default="joblib",
                   help="run in local processes (joblib) or on a Ray cluster "
                        "(default: %(default)s)")
    p.add_argument("--address", help="Ray cluster address (default: a local instance)")
    p.add_argument("--jobs", type=int, default=2,
                   help="parallel processes with --backend joblib, -1 for one per core "
                        "(default: %(default)s)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="folder of the leaderboard tables and plots (default: leaderboards, "
                        "leaderboards/nominal with --nominal)")
    p.set_defaults(func=_cmd_bench)

    for name in _PLUGGED:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            # a subcommand package that is not installed is skipped; a broken one raises
            if exc.name is None or not name.startswith(exc.name):
                raise
            continue
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``fricbench`` console script (exit 130 on Ctrl-C, no traceback)."""
    started = time.perf_counter()  # the bench's wall time counts its imports
    try:
        parser = build_parser()  # imports torch: long enough to be interrupted
        args = parser.parse_args(argv)
        args.started = started
    except KeyboardInterrupt:
        print("fricbench: interrupted", file=sys.stderr)
        return 130
    try:
        return int(args.func(args) or 0)
    except (ValueError, TypeError, KeyError, FileNotFoundError) as exc:
        print(f"fricbench {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # bench catches its own first, to write the finished runs
        print(f"fricbench {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
