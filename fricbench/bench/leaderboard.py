"""Leaderboard files: ``leaderboards/<env>.csv`` (raw rows), ``.md`` (tables), ``plots/``.

The plots are of the first seed: the error against time of each trajectory, and for a circle
the ballbar picture (:mod:`fricbench.axis.ballbar`; ``plots/<env>_circle_ballbar.png``), a
polar panel per compensator, both linked from the ``.md``.

A cell is one (env, compensator, trajectory, seed). A re-run replaces the rows of the cells it
ran and keeps every other row, except that a failed run never replaces a good row: the table
keeps the last good row of the cell, and the failure goes to ``<env>.failures.csv`` beside it
(the latest failure of each cell that has not succeeded since; the file is removed when no such
cell is left). A cell that never succeeded is in the table as a ``failed`` row. The ``Failed
runs`` section of the ``.md`` lists both kinds.
With ``fresh`` (``fricbench bench --fresh``, what ``make bench`` runs), the files of each env
the run scored hold this run's rows only: the rows, failures and seeds of earlier runs of that
env are dropped, so a table regenerated on fewer seeds is not a merge with older ones.

Each row records the constructor keywords its compensator was made with beyond the registered
defaults (``compensator_kwargs``, JSON; ``fricbench bench --compensator-kwargs``), and the
``.md`` lists them under "Compensator settings", so a table says what settings produced it.

Each row also records the command that wrote it and its commit (``command``, ``commit``), so
a table merged from several runs lists every command that contributed, with its commit and the
seeds of its rows.

Each ``.md`` reports per cell the median over seeds and its 95 % bootstrap interval of the max
and the RMS error and of the cut against ``none`` (:mod:`fricbench.bench.statistics`), with the
number of seeds of each row, and ranks the compensators overall and within each category
(:data:`fricbench.compensators.CATEGORIES`), marking neighbours whose per-seed difference is not
significant (paired on their common seeds; unpaired, and said so, when they share fewer than
two).

Per-step ``act`` times depend on the machine and its load, so they are kept out of these
tables: they go to ``timings/<env>.csv`` (untracked: ``leaderboards/timings/`` is in
``.gitignore``), and a re-run of the same code on the same seeds rewrites the tables with the
same bytes.

Every write is atomic (temp file + rename), and the read-merge-write of an env's files runs
under an exclusive ``fcntl.flock`` on ``<env>.lock`` beside them, so two benches writing the
same table at once lose no rows.
"""

from __future__ import annotations

import contextlib
import csv
import fcntl
import io
import json
import math
import os
from collections import defaultdict
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from fricbench._atomic import atomic_write
from fricbench.axis.ballbar import plot_ballbar
from fricbench.bench.error_budget import header_lines
from fricbench.bench.runner import EpisodeRecord
from fricbench.bench.statistics import (
    CONFIDENCE,
    MIN_SEEDS,
    N_RESAMPLES,
    Interval,
    cell_rng,
    median_ci,
    paired_difference,
    unpaired_difference,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "CSV_COLUMNS",
    "FAILURE_COLUMNS",
    "TARGETS",
    "TIMING_COLUMNS",
    "ballbar_plot_name",
    "Ranked",
    "compensator_category",
    "env_file_stem",
    "ranking",
    "summarise",
    "write_leaderboards",
]

_KEY = ("env", "compensator", "trajectory", "seed")
# compensator_kwargs: the constructor keywords of the run beyond the registered defaults, as
# JSON with sorted keys ("" for none); command, commit: the run that wrote the row ("" in rows
# written before rows recorded them)
CSV_COLUMNS = (*_KEY, "status", "max_um", "rms_um", "reversal_peak_um",
               "circular_deviation_um", "reversal_spike_um", "improvement_max_pct", "effort_rms",
               "effort_unit", "reason", "compensator_kwargs", "category", "plant", "command",
               "commit")
# untracked: timings/<env>.csv
TIMING_COLUMNS = (*_KEY, "step_us")
# <env>.failures.csv: the latest failure of each cell not run successfully since
FAILURE_COLUMNS = (*_KEY, "commit", "reason")

# issue targets: minimum median cut of max |e| against `none` on held-out m_serial and curve
TARGETS = {"ilc": 90.0, "kalman": 50.0, "rl-sac": 30.0}
TARGET_BEST = 80.0
TARGET_TRAJECTORIES = ("m_serial", "curve")


def env_file_stem(env_id: str) -> str:
    """``fricbench/PaperAxis-v0`` -> ``PaperAxis-v0``."""
    return env_id.split("/", 1)[-1]


def ballbar_plot_name(env_id: str, trajectory: str) -> str:
    """File name of the ballbar plot of a circle trajectory, under ``plots/``."""
    return f"{env_file_stem(env_id)}_{trajectory}_ballbar.png"


def _um(x: float) -> str:
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x * 1e6:.3f}"


def _record_rows(records: Iterable[EpisodeRecord]) -> list[dict[str, str]]:
    rows = []
    for r in records:
        eff = "" if math.isnan(r.effort_rms) else (
            f"{r.effort_rms:.4g}" if r.effort_unit == "N" else f"{r.effort_rms * 1e6:.4g}")
        rows.append({
            "env": r.env, "compensator": r.compensator, "trajectory": r.trajectory,
            "seed": str(r.seed), "status": r.status, "max_um": _um(r.max_error),
            "rms_um": _um(r.rms_error), "reversal_peak_um": _um(r.reversal_peak),
            "circular_deviation_um": _um(r.circular_deviation),
            "reversal_spike_um": _um(r.reversal_spike), "improvement_max_pct": "",
            "effort_rms": eff, "effort_unit": {"N": "N", "m": "um"}.get(r.effort_unit, ""),
            "reason": r.reason, "compensator_kwargs": _settings_text(r.compensator_kwargs),
            "category": compensator_category(r.compensator), "plant": r.plant,
        })
    return rows


def compensator_category(comp_id: str) -> str:
    """The category a compensator declares (``Compensator.category``); ``""`` when its class
    cannot be loaded or declares none."""
    from fricbench.compensators import CATEGORIES, PRECOMP_PREFIX, compensator_registry

    if comp_id.startswith(PRECOMP_PREFIX):
        return "model"
    try:
        cat = str(getattr(compensator_registry.spec(comp_id).load(), "category", ""))
    except Exception:  # noqa: BLE001 - an unloadable plug-in still gets its rows written
        return ""
    return cat if cat in CATEGORIES else ""


def _settings_text(kwargs: dict[str, object]) -> str:
    """Constructor keywords as one-line JSON with sorted keys; ``""`` for none."""
    return json.dumps(kwargs, sort_keys=True, default=str) if kwargs else ""


def _settings_lines(rows: list[dict[str, str]], comps: Sequence[str]) -> list[str]:
    """The ``Compensator settings`` bullet of the table: each compensator's keywords (all the
    distinct ones, when rows of several runs with other settings are merged)."""
    lines = []
    for c in comps:
        kinds = sorted({r.get("compensator_kwargs", "") for r in rows if r["compensator"] == c},
                       key=lambda k: (k == "", k))  # the defaults last
        if kinds != [""]:
            shown = ", ".join(f"`{k}`" if k else "the defaults" for k in kinds)
            mixed = " (rows from runs with different settings)" if len(kinds) > 1 else ""
            lines.append(f"  - `{c}`: {shown}{mixed}\n")
    if not lines:
        return []
    files = sorted({w[i + 1] for r in rows for w in [r.get("command", "").split()]
                    for i in range(len(w) - 1) if w[i] == "--compensator-config"})
    why = (f"; why each differs from the default, a cut training budget included: the comments "
           f"of {', '.join(f'`{f}`' for f in files)}" if files else "")
    return ["- Compensator settings (constructor keywords over the registered defaults; the "
            f"CSV's compensator_kwargs column{why}):\n", *lines]


def _timing_rows(records: Iterable[EpisodeRecord]) -> list[dict[str, str]]:
    return [{"env": r.env, "compensator": r.compensator, "trajectory": r.trajectory,
             "seed": str(r.seed), "step_us": f"{r.step_time * 1e6:.2f}"}
            for r in records if r.status == "ok" and not math.isnan(r.step_time)]


def _key(row: dict[str, str]) -> tuple[str, str, str]:
    return row.get("compensator", ""), row.get("trajectory", ""), row.get("seed", "")


def _sort_key(row: dict[str, str]) -> tuple[bool, str, str, int]:
    return row["compensator"] != "none", row["compensator"], row["trajectory"], int(row["seed"])


def _csv_text(rows: list[dict[str, str]], columns: Sequence[str]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """Hold an exclusive ``flock`` on ``path`` (created if missing; never removed)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing the descriptor releases the lock


def _read_csv(path: Path) -> list[dict[str, str]]:
    if not path.exists():
        return []
    with path.open(newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames is None or "env" not in reader.fieldnames:
            raise ValueError(f"{path}: not a fricbench leaderboard CSV (no 'env' column)")
        return [dict(row) for row in reader]


def _improvements(rows: list[dict[str, str]]) -> None:
    base = {(r["trajectory"], r["seed"]): r["max_um"] for r in rows
            if r["compensator"] == "none" and r["status"] == "ok" and r["max_um"]}
    for r in rows:
        ref = base.get((r["trajectory"], r["seed"]))
        if r["status"] == "ok" and r["max_um"] and ref and float(ref) > 0.0:
            r["improvement_max_pct"] = f"{100.0 * (1.0 - float(r['max_um']) / float(ref)):.1f}"
        else:
            r["improvement_max_pct"] = ""


def _median(vals: list[float]) -> float:
    return float(np.median(vals)) if vals else float("nan")


def summarise(rows: list[dict[str, str]]) -> dict[str, dict[str, dict[str, float]]]:
    """``{compensator: {trajectory: {metric: median over seeds}}}`` of the ok rows."""
    acc: dict[str, dict[str, dict[str, list[float]]]] = defaultdict(
        lambda: defaultdict(lambda: defaultdict(list)))
    for r in rows:
        if r["status"] != "ok":
            continue
        for key in ("max_um", "rms_um", "reversal_peak_um", "improvement_max_pct",
                    "circular_deviation_um"):
            if r.get(key):
                acc[r["compensator"]][r["trajectory"]][key].append(float(r[key]))
    return {c: {t: {k: _median(v) for k, v in m.items()} for t, m in tr.items()}
            for c, tr in acc.items()}


def _per_seed(rows: list[dict[str, str]], comp: str, traj: str, key: str) -> dict[int, float]:
    """``{seed: value}`` of the ok rows of one cell (finite values only)."""
    out = {}
    for r in rows:
        if r["compensator"] == comp and r["trajectory"] == traj and r["status"] == "ok" \
                and r.get(key):
            v = float(r[key])
            if math.isfinite(v):
                out[int(r["seed"])] = v
    return out


def _cell(rows: list[dict[str, str]], seeds: Sequence[int], comp: str, traj: str, key: str,
          fmt: str = ".2f", sign: bool = False) -> str:
    vals = _per_seed(rows, comp, traj, key)
    if not vals:
        fails = any(r["compensator"] == comp and r["trajectory"] == traj and
                    r["status"] != "ok" for r in rows)
        return "failed" if fails else "-"
    ci = median_ci(list(vals.values()), cell_rng(seeds, comp, traj, key))
    return ci.text(fmt, sign)


def _scores(rows: list[dict[str, str]], comp: str, trajs: Sequence[str]) -> dict[int, float]:
    """Per seed: the mean over ``trajs`` of the cut of max |e| against ``none`` (%), for the
    seeds on which every trajectory has an ok row of ``comp`` and of ``none``."""
    cuts = [_per_seed(rows, comp, t, "improvement_max_pct") for t in trajs]
    common = set.intersection(*(set(c) for c in cuts)) if cuts else set()
    return {s: float(np.mean([c[s] for c in cuts])) for s in sorted(common)}


class Ranked(NamedTuple):
    """One line of :func:`ranking`."""

    compensator: str
    score: Interval
    """The median over its seeds of its mean cut against ``none`` (%); ``n`` its seeds."""
    to_next: Interval | None
    """This one minus the next one down (None for the last): significant when its interval
    excludes 0."""
    paired: bool
    """``to_next`` is the median of per-seed differences on the seeds both have (True), or the
    difference of the two medians, each over its own seeds (False: they share fewer than two
    seeds, as in a table merged from runs on other seeds)."""


def ranking(rows: list[dict[str, str]], comps: Sequence[str], trajs: Sequence[str],
            seeds: Sequence[int], label: str = "overall") -> list[Ranked]:
    """Rank ``comps`` by the median over seeds of their mean cut against ``none``.

    Best first. Two neighbours sharing at least two seeds are compared per seed on those
    (:func:`~fricbench.bench.statistics.paired_difference`: seeds share plants); otherwise by
    :func:`~fricbench.bench.statistics.unpaired_difference`. Compensators without a complete
    seed are left out.
    """
    scored = [(c, _scores(rows, c, trajs)) for c in comps]
    scored = [(c, sc) for c, sc in scored if sc]
    with_ci = [(c, sc, median_ci(list(sc.values()), cell_rng(seeds, c, "score")))
               for c, sc in scored]
    with_ci.sort(key=lambda x: (-x[2].median, x[0]))
    out = []
    for i, (c, sc, ci) in enumerate(with_ci):
        diff, paired = None, True
        if i + 1 < len(with_ci):
            nxt = with_ci[i + 1]
            paired = len(sc.keys() & nxt[1].keys()) >= 2
            diff = (paired_difference(sc, nxt[1], cell_rng(seeds, label, c, nxt[0])) if paired
                    else unpaired_difference(sc, nxt[1],
                                             cell_rng(seeds, label, c, nxt[0], "unpaired")))
        out.append(Ranked(c, ci, diff, paired))
    return out


def _seeds_caveat(n_seeds: int) -> str:
    """What the intervals of ``n_seeds`` seeds are worth, for the tables' headings ("" from
    :data:`~fricbench.bench.statistics.MIN_SEEDS` seeds on)."""
    if n_seeds <= 1:
        return " (1 seed: no interval exists; ranked by the point value)"
    if n_seeds < MIN_SEEDS:
        held = 100.0 * (1.0 - 2.0 ** (1 - n_seeds))
        return (f" (only {n_seeds} seeds: a {CONFIDENCE * 100:g} % interval of a median needs "
                f"at least {MIN_SEEDS}; the range of {n_seeds} holds the median {held:.0f} % "
                "of the time: read the intervals and n.s. as rough)")
    return ""


def _ranking_table(rows: list[dict[str, str]], comps: Sequence[str], trajs: Sequence[str],
                   seeds: Sequence[int], label: str, cats: dict[str, str]) -> list[str]:
    ranked = ranking(rows, comps, trajs, seeds, label)
    if not ranked:
        return ["(no compensator with a complete seed)\n"]
    lines = ["| rank | compensator | category | n | mean cut of max abs(e) (%) | to the next "
             "(%) |\n", "|---|---|---|---|---|---|\n"]
    rank = 1
    for i, (c, ci, diff, paired) in enumerate(ranked):
        if diff is None:
            vs = ""
        else:
            vs = diff.text(".1f", sign=True) + ("" if paired else " (unpaired)")
            if diff.has_ci and not diff.excludes_zero():
                vs += " **n.s.**"
        # a tie only where an interval says so; without one the point values rank
        prev = ranked[i - 1].to_next if i > 0 else None
        tie = prev is not None and prev.has_ci and not prev.excludes_zero()
        shown = f"= {rank}" if tie else str(i + 1)
        if not tie:
            rank = i + 1
        lines.append(f"| {shown} | `{c}` | {cats.get(c, '') or '-'} | {ci.n} | "
                     f"{ci.text('.1f', True)} | {vs} |\n")
    return lines


def _markdown(env_id: str, rows: list[dict[str, str]], failures: list[dict[str, str]],
              description: str, fit_on: str,
              ballbars: Sequence[str] = ()) -> str:
    from fricbench.compensators import CATEGORIES

    summary = summarise(rows)
    trajs = sorted({r["trajectory"] for r in rows})
    comps = sorted({r["compensator"] for r in rows}, key=lambda c: (c != "none", c))
    seeds = sorted({int(r["seed"]) for r in rows})
    cats = {c: compensator_category(c) for c in comps}
    plants = sorted({r.get("plant", "") or "nominal" for r in rows})
    circle = any(r["circular_deviation_um"] for r in rows)
    out = io.StringIO()
    out.write(f"# Leaderboard: `{env_id}`\n\n{description}\n\n")
    out.writelines(_provenance_lines(rows, seeds))
    out.writelines(header_lines(env_id, trajs, comps))
    if plants == ["seed"]:
        out.write("- Plants: each seed is a machine drawn around the env's nominal axis "
                  "(friction levels, Stribeck velocity, mass, damping; encoder and current "
                  "noise: `fricbench/bench/plants.py`), the same for every compensator; each "
                  "compensator that learns is fitted on training runs of that seed's plant\n")
    elif plants == ["nominal"]:
        out.write("- Plants: the env's nominal, noise-free axis on every seed (`--nominal`): "
                  "the seeds are copies and the intervals collapse\n")
    else:
        out.write("- Plants: rows of drawn plants and of the nominal axis mixed (re-run every "
                  "seed in one mode)\n")
    if fit_on != env_id:
        out.write(f"- Generalisation case: compensators fitted on `{fit_on}`\n")
    out.writelines(_settings_lines(rows, comps))
    out.write(f"- Statistics: per cell the median over seeds and its {CONFIDENCE:.0%} bootstrap "
              f"confidence interval [low, high] (`scipy.stats.bootstrap`, percentile method, "
              f"{N_RESAMPLES} resamples, generator seeded from the seeds and the cell: the "
              "same rows give the same table). Cut against `none`: per seed "
              "100 (1 - max/max_none) on the same plant. Raw per-seed rows: the CSV beside "
              "this file.\n")
    out.write("- Categories (what a compensator uses beyond the scored run): `trials` "
              "rehearses the scored reference, `model` is fitted on training runs, `online` "
              "adapts while it runs, `policy` is learned offline. `none` (no compensation) is "
              "the reference of every category.\n")
    out.write("- Ranking: overall and within each category, by the median over seeds of the "
              "mean over trajectories of the cut against `none`. *To the next*: the median "
              "over seeds of the per-seed difference to the next one down and its interval "
              "(paired bootstrap on the seeds both have: seeds share plants); marked "
              "*(unpaired)* when the two share fewer than two seeds: the difference of their "
              "medians, each resampled over its own seeds; **n.s.** when the interval contains "
              "0, and the next one then shares the rank (`= k`). *n*: the seeds of the row.\n\n")
    caveat = _seeds_caveat(len(seeds))
    ci_head = f" [{CONFIDENCE * 100:g} % CI]" if len(seeds) > 1 else ""

    def table(title: str, key: str, fmt: str, sign: bool, extra: bool) -> None:
        out.write(f"## {title}{ci_head}{caveat}\n\n")
        head = "| compensator | category | n | " + " | ".join(trajs) + " |"
        if extra:
            head += " reversal peak (um, median) |" + (" circular dev. (um) |" if circle else "")
        out.write(head + "\n")
        n_cols = len(trajs) + 3 + ((2 if circle else 1) if extra else 0)
        out.write("|" + "---|" * n_cols + "\n")
        for c in comps:
            if sign and c == "none":
                continue
            cells = [_cell(rows, seeds, c, t, key, fmt, sign) for t in trajs]
            n = _n_text([len(_per_seed(rows, c, t, key)) for t in trajs])
            line = f"| `{c}` | {cats[c] or '-'} | {n} | " + " | ".join(cells) + " |"
            if extra:
                line += " " + _fmt(_median([m["reversal_peak_um"] for m in
                                            summary.get(c, {}).values()
                                            if "reversal_peak_um" in m])) + " |"
                if circle:
                    line += " " + _fmt(_median([m["circular_deviation_um"] for m in
                                                summary.get(c, {}).values()
                                                if "circular_deviation_um" in m])) + " |"
            out.write(line + "\n")
        out.write("\n")

    table("Max abs(e) (um): median", "max_um", ".2f", False, True)
    table("Cut of max abs(e) against `none` (%): median", "improvement_max_pct", ".1f", True,
          False)
    table("RMS error (um): median", "rms_um", ".3f", False, False)
    out.write(f"## Ranking{caveat}\n\n### Overall\n\n")
    out.writelines(_ranking_table(rows, comps, trajs, seeds, "overall", cats))
    for cat in CATEGORIES:
        members = [c for c in comps if cats[c] == cat and c != "none"]
        if not members:
            continue
        out.write(f"\n### Within `{cat}`\n\n")
        out.writelines(_ranking_table(rows, ["none", *members], trajs, seeds, cat, cats))
    targets = _target_lines(summary, env_id)
    if targets:
        out.write("\n## Targets (median over seeds, held-out m_serial and curve)\n\n")
        out.writelines(targets)
    ok_cells = {_key(r) for r in rows if r["status"] == "ok"}
    failed_cells = {_key(f) for f in failures}
    failed = [(f, _key(f) in ok_cells) for f in failures]
    failed += [(r, False) for r in rows if r["status"] != "ok" and _key(r) not in failed_cells]
    if failed:
        out.write("\n## Failed runs\n\n| compensator | trajectory | seed | reason | table shows |\n"
                  "|---|---|---|---|---|\n")
        seen = set()
        for r, kept in sorted(failed, key=lambda fk: _sort_key(fk[0])):
            key = (r["compensator"], r["reason"], kept)
            if key in seen:
                continue
            seen.add(key)
            shows = "the earlier good row" if kept else "failed"
            out.write(f"| `{r['compensator']}` | {r['trajectory']} | {r['seed']} | "
                      f"{r['reason'].replace('|', '/')} | {shows} |\n")
    plots = sorted({r["trajectory"] for r in rows})
    out.write("\n## Error traces (first seed)\n\n")
    for t in plots:
        out.write(f"![{t}](plots/{env_file_stem(env_id)}_{t}.png)\n")
    if ballbars:
        out.write("\n## Ballbar (first seed)\n\n"
                  "The radius about the circle's centre against the angle, radial deviation "
                  "magnified (the factor and the scale are on the plot): quadrant glitches at "
                  "0, 90, 180 and 270 degrees, where an axis reverses.\n\n")
        for t in ballbars:
            out.write(f"![{t} ballbar](plots/{ballbar_plot_name(env_id, t)})\n")
    return out.getvalue()


def _n_text(counts: Sequence[int]) -> str:
    """The seeds of a table row: ``"10"``, or ``"2-4"`` when its cells have different ones
    (cells without a value not counted)."""
    ns = sorted({n for n in counts if n})
    if not ns:
        return "0"
    return str(ns[0]) if len(ns) == 1 else f"{ns[0]}-{ns[-1]}"


def _provenance_lines(rows: list[dict[str, str]], seeds: Sequence[int]) -> list[str]:
    """The ``Made by``, ``Commit`` and ``Seeds`` lines: the run that wrote every row, or each
    run that contributed rows (merged tables), with its commit and the seeds of its rows."""
    runs: dict[tuple[str, str], list[dict[str, str]]] = defaultdict(list)
    for r in rows:
        runs[(r.get("command", ""), r.get("commit", ""))].append(r)
    per_comp = {c: {r["seed"] for r in rows if r["compensator"] == c}
                for c in {r["compensator"] for r in rows}}
    whole = len({frozenset(v) for v in per_comp.values()}) == 1
    n_text = (f"(n = {len(seeds)})" if whole else
              "(their union; the rows have different seeds: n per row in the tables)")
    if len(runs) == 1 and all(next(iter(runs))):
        command, commit = next(iter(runs))
        return [f"- Made by: `{command}`\n", f"- Commit: `{commit}`\n",
                f"- Seeds: {list(seeds)} {n_text}\n"]
    lines = ["- Made by (rows merged from several runs: each command, its commit and the seeds "
             "of its rows):\n"]
    for (command, commit), rs in sorted(runs.items(), key=lambda kv: (not kv[0][0], kv[0])):
        run_seeds = sorted({int(r["seed"]) for r in rs})
        comps = sorted({r["compensator"] for r in rs}, key=lambda c: (c != "none", c))
        what = (f"seeds {run_seeds}, {len(rs)} row{'' if len(rs) == 1 else 's'} "
                f"({', '.join(f'`{c}`' for c in comps)})")
        if command:
            lines.append(f"  - `{command}` at commit `{commit or 'unknown'}`: {what}\n")
        else:
            lines.append(f"  - not recorded (rows written before rows named their command): "
                         f"{what}\n")
    lines.append(f"- Seeds: {list(seeds)} {n_text}\n")
    return lines


def _fmt(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.2f}"


def _target_lines(summary: dict[str, dict[str, dict[str, float]]], env_id: str) -> list[str]:
    if "fricbench/PaperAxis-v0" != env_id:
        return []
    lines = []

    def cut(c: str) -> float:
        vals = [summary.get(c, {}).get(t, {}).get("improvement_max_pct", float("nan"))
                for t in TARGET_TRAJECTORIES]
        return min(vals) if vals else float("nan")

    cuts = {c: cut(c) for c in summary if c != "none"}
    finite = {c: v for c, v in cuts.items() if not math.isnan(v)}
    # the best-compensator target speaks for the field: only when every targeted one is scored
    if finite and all(c in finite for c in TARGETS):
        best = max(finite, key=lambda c: finite[c])
        ok = finite[best] >= TARGET_BEST
        lines.append(f"- best compensator `{best}`: {finite[best]:.1f} % (target >= "
                     f"{TARGET_BEST:.0f} %): {'met' if ok else 'MISSED'}\n")
    for c, target in TARGETS.items():
        if c in finite:  # only what was run (and scored on the target trajectories)
            lines.append(f"- `{c}`: {finite[c]:.1f} % (target >= {target:.0f} %): "
                         f"{'met' if finite[c] >= target else 'MISSED'}\n")
    return lines


_TRACE_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown",
                 "tab:pink", "tab:olive", "tab:cyan")
_TRACE_DASHES = ("-", (0, (5, 1.5)), (0, (3, 1, 1, 1)), (0, (1, 1)))
"""Colour and dash of the i-th compensator's trace: ``(i mod 9, i mod 4)``, a distinct pair for
up to 36 compensators (``none`` is the grey baseline)."""


def _trace_figure(env_id: str, trajectory: str, records: Sequence[EpisodeRecord]) -> Figure:
    """The error traces of ``records`` on one axis: ``none`` as a wide grey baseline at the
    bottom, every other compensator in its own colour and dash, drawn in order of decreasing
    maximum error (the smallest error on top, where the traces crowd about zero), the legend
    outside the axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.5), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    # two-axis runs trace their contour error (the scored quantity): the envs' axis count
    contour = any(r.circular_deviation is not None and np.isfinite(r.circular_deviation)
                  for r in records)
    traced = [(r, r.trace_t, r.trace_error * 1e6)
              for r in sorted(records, key=lambda r: (r.compensator != "none", r.compensator))
              if r.trace_t is not None and r.trace_error is not None]
    # z-order: the larger the maximum error, the lower the trace
    by_size = sorted((r for r, _, _ in traced),
                     key=lambda r: -r.max_error if np.isfinite(r.max_error) else 0.0)
    z = {r.compensator: 2.0 + i for i, r in enumerate(by_size)}
    i = 0
    for r, t, e_um in traced:
        label = f"{r.compensator} (max |e| {r.max_error * 1e6:.1f} um)"
        if r.compensator == "none":
            ax.plot(t, e_um, color="0.6", lw=2.4, zorder=1.0, label=label)
            continue
        ax.plot(t, e_um, color=_TRACE_COLORS[i % len(_TRACE_COLORS)],
                linestyle=_TRACE_DASHES[i % len(_TRACE_DASHES)], lw=1.1, alpha=0.85,
                zorder=z[r.compensator], label=label)
        i += 1
    ax.set_title(f"{env_id}: {trajectory}, seed {records[0].seed}"
                 + (" (maxima over the full-rate run)" if contour else ""))
    ax.set_xlabel("time [s]")
    ax.set_ylabel("contour error [um]" if contour else "tracking error [um]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0,
              title="smaller max |e| drawn on top", title_fontsize=7)
    return fig


def _plot(env_id: str, trajectory: str, records: Sequence[EpisodeRecord], path: Path) -> None:
    fig = _trace_figure(env_id, trajectory, records)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    atomic_write(path, buf.getvalue())


def _plot_ballbar(env_id: str, trajectory: str, records: Sequence[EpisodeRecord],
                  path: Path) -> None:
    """The ballbar picture of the records' circle runs: a panel per compensator, ``none`` in
    grey behind the others, one magnification for all."""
    runs = {r.compensator: r.trace_ballbar
            for r in sorted(records, key=lambda r: (r.compensator != "none", r.compensator))
            if r.trace_ballbar is not None}
    plot_ballbar(runs, f"{env_id}: {trajectory}, seed {records[0].seed}: ballbar (radial "
                       "deviation about the nominal circle)", path,
                 baseline="none" if "none" in runs and len(runs) > 1 else None)


def write_leaderboards(records: Sequence[EpisodeRecord], out_dir: str | Path, command: str,
                       commit: str, descriptions: dict[str, tuple[str, str]],
                       fresh: bool = False) -> list[Path]:
    """Merge ``records`` into the leaderboard files of their envs; return the written paths.

    ``descriptions`` maps env id to ``(description, fit_on)``. Each env's files are merged
    under the lock of ``<env>.lock``; a failed record never replaces a good row (see the
    module docstring). With ``fresh``, the files of each env in ``records`` are written from
    ``records`` alone, the earlier rows and failures of that env dropped.
    """
    out = Path(out_dir)
    written = []
    by_env: dict[str, list[EpisodeRecord]] = defaultdict(list)
    for r in records:
        by_env[r.env].append(r)
    for env_id, recs in sorted(by_env.items()):
        stem = env_file_stem(env_id)
        desc, fit_on = descriptions.get(env_id, ("", env_id))
        with _locked(out / f"{stem}.lock"):
            written += _merge_env(env_id, recs, out, stem, command, commit, desc, fit_on,
                                  fresh)
    return written


def _merge_env(env_id: str, recs: Sequence[EpisodeRecord], out: Path, stem: str, command: str,
               commit: str, desc: str, fit_on: str, fresh: bool = False) -> list[Path]:
    """Read, merge and rewrite the files of one env (the caller holds its lock); with
    ``fresh``, write them from ``recs`` alone."""
    csv_path = out / f"{stem}.csv"
    fail_path = out / f"{stem}.failures.csv"
    time_path = out / "timings" / f"{stem}.csv"
    new_rows = _record_rows(recs)
    for row in new_rows:
        row["command"], row["commit"] = command, commit
    old_rows = {} if fresh else {_key(r): {c: r.get(c, "") for c in CSV_COLUMNS}
                                 for r in _read_csv(csv_path)}
    failures = {} if fresh else {_key(r): {c: r.get(c, "") for c in FAILURE_COLUMNS}
                                 for r in _read_csv(fail_path)}
    merged = dict(old_rows)
    for row in new_rows:
        k = _key(row)
        if row["status"] == "ok":
            merged[k] = row
            failures.pop(k, None)
        else:
            failures[k] = {**{c: row[c] for c in _KEY}, "commit": commit,
                           "reason": row["reason"]}
            if merged.get(k, {}).get("status") != "ok":  # never replace a good row
                merged[k] = row
    rows = sorted(merged.values(), key=_sort_key)
    _improvements(rows)
    cats: dict[str, str] = {}
    for row in rows:  # derived columns: the category declared now; rows from before plants
        # were drawn ran the nominal axis
        row["category"] = cats.setdefault(row["compensator"],
                                          compensator_category(row["compensator"]))
        row["plant"] = row.get("plant") or "nominal"
    fail_rows = sorted(failures.values(), key=_sort_key)
    atomic_write(csv_path, _csv_text(rows, CSV_COLUMNS))
    written = [csv_path]
    if fail_rows:
        atomic_write(fail_path, _csv_text(fail_rows, FAILURE_COLUMNS))
        written.append(fail_path)
    elif fail_path.exists():
        fail_path.unlink()
    timing_new = _timing_rows(recs)
    if timing_new:
        timings = {_key(r): {c: r.get(c, "") for c in TIMING_COLUMNS}
                   for r in _read_csv(time_path)}
        timings.update((_key(r), r) for r in timing_new)
        atomic_write(time_path, _csv_text(sorted(timings.values(), key=_sort_key),
                                          TIMING_COLUMNS))
        written.append(time_path)
    by_traj: dict[str, list[EpisodeRecord]] = defaultdict(list)
    for r in recs:
        if r.trace_t is not None:
            by_traj[r.trajectory].append(r)
    for traj, trs in by_traj.items():
        p = out / "plots" / f"{stem}_{traj}.png"
        _plot(env_id, traj, trs, p)
        written.append(p)
        if any(r.trace_ballbar is not None for r in trs):
            p = out / "plots" / ballbar_plot_name(env_id, traj)
            _plot_ballbar(env_id, traj, trs, p)
            written.append(p)
    # a ballbar plot of an earlier run stays linked when this run drew none (a failed seed)
    ballbars = [t for t in sorted({r["trajectory"] for r in rows})
                if (out / "plots" / ballbar_plot_name(env_id, t)).exists()]
    atomic_write(out / f"{stem}.md",
                 _markdown(env_id, rows, fail_rows, desc, fit_on, ballbars))
    written.append(out / f"{stem}.md")
    return written
