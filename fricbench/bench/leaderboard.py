"""Leaderboard files: ``leaderboards/<env>.csv`` (raw rows), ``.md`` (tables), ``plots/``.

Writes are atomic (temp file + rename). A re-run replaces the rows it produced (same env,
compensator, trajectory, seed) and keeps every other row.
"""

from __future__ import annotations

import csv
import io
import math
from collections import defaultdict
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from fricbench._atomic import atomic_write
from fricbench.bench.runner import EpisodeRecord

__all__ = [
    "CSV_COLUMNS",
    "TARGETS",
    "env_file_stem",
    "summarise",
    "write_leaderboards",
]

CSV_COLUMNS = ("env", "compensator", "trajectory", "seed", "status", "max_um", "rms_um",
               "reversal_peak_um", "circular_deviation_um", "reversal_spike_um",
               "improvement_max_pct", "effort_rms", "effort_unit", "step_us", "reason")

# issue targets: minimum median cut of max |e| against `none` on held-out m_serial and curve
TARGETS = {"ilc": 90.0, "kalman": 50.0, "rl-sac": 30.0}
TARGET_BEST = 80.0
TARGET_TRAJECTORIES = ("m_serial", "curve")


def env_file_stem(env_id: str) -> str:
    """``fricbench/PaperAxis-v0`` -> ``PaperAxis-v0``."""
    return env_id.split("/", 1)[-1]


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
            "step_us": "" if math.isnan(r.step_time) else f"{r.step_time * 1e6:.2f}",
            "reason": r.reason,
        })
    return rows


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
        if r["status"] == "ok" and r["max_um"] and ref:
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
        for key in ("max_um", "rms_um", "reversal_peak_um", "improvement_max_pct", "step_us",
                    "circular_deviation_um"):
            if r.get(key):
                acc[r["compensator"]][r["trajectory"]][key].append(float(r[key]))
    return {c: {t: {k: _median(v) for k, v in m.items()} for t, m in tr.items()}
            for c, tr in acc.items()}


def _markdown(env_id: str, rows: list[dict[str, str]], command: str, commit: str,
              description: str, fit_on: str) -> str:
    summary = summarise(rows)
    trajs = sorted({r["trajectory"] for r in rows})
    comps = sorted({r["compensator"] for r in rows}, key=lambda c: (c != "none", c))
    seeds = sorted({int(r["seed"]) for r in rows})
    circle = any(r["circular_deviation_um"] for r in rows)
    out = io.StringIO()
    out.write(f"# Leaderboard: `{env_id}`\n\n{description}\n\n")
    out.write(f"- Made by: `{command}`\n- Commit: `{commit}`\n- Seeds: {seeds}\n")
    if fit_on != env_id:
        out.write(f"- Generalisation case: compensators fitted on `{fit_on}`\n")
    out.write("- Metric: median over seeds of max |e| in um (actual tracking error; contour "
              "error for two axes), and its cut against `none` in %. Raw rows: the CSV beside "
              "this file.\n\n")
    head = "| compensator | " + " | ".join(trajs) + " | reversal peak (um, median) |"
    if circle:
        head += " circular dev. (um) |"
    head += " act time (us/step) |\n"
    out.write(head)
    out.write("|" + "---|" * (len(trajs) + 3 + (1 if circle else 0)) + "\n")
    for c in comps:
        cells = []
        for t in trajs:
            m = summary.get(c, {}).get(t)
            if not m or "max_um" not in m:
                fails = [r["reason"] for r in rows if r["compensator"] == c and
                         r["trajectory"] == t and r["status"] != "ok"]
                cells.append("failed" if fails else "-")
                continue
            imp = m.get("improvement_max_pct")
            cells.append(f"{m['max_um']:.2f}" + (f" ({imp:+.0f} %)" if imp is not None and
                                                   c != "none" and not math.isnan(imp) else ""))
        rev = _median([m["reversal_peak_um"] for m in summary.get(c, {}).values()
                       if "reversal_peak_um" in m])
        line = f"| `{c}` | " + " | ".join(cells) + f" | {rev:.2f} |"
        if circle:
            cd = _median([m["circular_deviation_um"] for m in summary.get(c, {}).values()
                          if "circular_deviation_um" in m])
            line += f" {cd:.2f} |"
        st = _median([m["step_us"] for m in summary.get(c, {}).values() if "step_us" in m])
        line += f" {st:.1f} |\n"
        out.write(line)
    targets = _target_lines(summary, env_id)
    if targets:
        out.write("\n## Targets (median over seeds, held-out m_serial and curve)\n\n")
        out.writelines(targets)
    failed = [r for r in rows if r["status"] != "ok"]
    if failed:
        out.write("\n## Failed runs\n\n| compensator | trajectory | seed | reason |\n"
                  "|---|---|---|---|\n")
        seen = set()
        for r in failed:
            key = (r["compensator"], r["reason"])
            if key in seen:
                continue
            seen.add(key)
            out.write(f"| `{r['compensator']}` | {r['trajectory']} | {r['seed']} | "
                      f"{r['reason'].replace('|', '/')} |\n")
    plots = sorted({r["trajectory"] for r in rows})
    out.write("\n## Error traces (first seed)\n\n")
    for t in plots:
        out.write(f"![{t}](plots/{env_file_stem(env_id)}_{t}.png)\n")
    return out.getvalue()


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
    if finite:
        best = max(finite, key=lambda c: finite[c])
        ok = finite[best] >= TARGET_BEST
        lines.append(f"- best compensator `{best}`: {finite[best]:.1f} % (target >= "
                     f"{TARGET_BEST:.0f} %): {'met' if ok else 'MISSED'}\n")
    for c, target in TARGETS.items():
        v = cuts.get(c, float("nan"))
        state = "not run" if math.isnan(v) else ("met" if v >= target else "MISSED")
        lines.append(f"- `{c}`: {v:.1f} % (target >= {target:.0f} %): {state}\n")
    return lines


def _plot(env_id: str, trajectory: str, records: Sequence[EpisodeRecord], path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 4.5), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    for r in sorted(records, key=lambda r: (r.compensator != "none", r.compensator)):
        if r.trace_t is None or r.trace_error is None:
            continue
        e = r.trace_error if r.trace_error.ndim == 1 else np.hypot(*r.trace_error)
        ax.plot(r.trace_t, e * 1e6, lw=1.0 if r.compensator != "none" else 1.6,
                label=f"{r.compensator} (max {r.max_error * 1e6:.1f} um)")
    ax.set_title(f"{env_id}: {trajectory}, seed {records[0].seed}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tracking error [um]" if records[0].trace_error is None or
                  records[0].trace_error.ndim == 1 else "|error| [um]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right", ncol=2)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    atomic_write(path, buf.getvalue())


def write_leaderboards(records: Sequence[EpisodeRecord], out_dir: str | Path, command: str,
                       commit: str, descriptions: dict[str, tuple[str, str]]) -> list[Path]:
    """Merge ``records`` into the leaderboard files of their envs; return the written paths.

    ``descriptions`` maps env id to ``(description, fit_on)``.
    """
    out = Path(out_dir)
    written = []
    by_env: dict[str, list[EpisodeRecord]] = defaultdict(list)
    for r in records:
        by_env[r.env].append(r)
    for env_id, recs in sorted(by_env.items()):
        stem = env_file_stem(env_id)
        csv_path = out / f"{stem}.csv"
        new_rows = _record_rows(recs)
        keys = {(r["compensator"], r["trajectory"], r["seed"]) for r in new_rows}
        old = [r for r in _read_csv(csv_path)
               if (r.get("compensator"), r.get("trajectory"), r.get("seed")) not in keys]
        rows = [{c: r.get(c, "") for c in CSV_COLUMNS} for r in old] + new_rows
        rows.sort(key=lambda r: (r["compensator"] != "none", r["compensator"], r["trajectory"],
                                 int(r["seed"])))
        _improvements(rows)
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
        atomic_write(csv_path, buf.getvalue())
        desc, fit_on = descriptions.get(env_id, ("", env_id))
        atomic_write(out / f"{stem}.md", _markdown(env_id, rows, command, commit, desc, fit_on))
        written += [csv_path, out / f"{stem}.md"]
        by_traj: dict[str, list[EpisodeRecord]] = defaultdict(list)
        for r in recs:
            if r.trace_t is not None:
                by_traj[r.trajectory].append(r)
        for traj, trs in by_traj.items():
            p = out / "plots" / f"{stem}_{traj}.png"
            _plot(env_id, traj, trs, p)
            written.append(p)
    return written
