"""The committed leaderboards match the code: a sample of their rows, rerun now, gives the same
bytes.

For each ``leaderboards/<env>.csv``, the cells of a few compensators (:data:`SAMPLE`, those the
table has) on its first :data:`N_SEEDS` seeds and every trajectory are rerun through
:func:`~fricbench.bench.runner.run_benchmark` (the bench's own path: its fits, its cells, its
seeds) with the settings and the plant mode the rows record, written by
:func:`~fricbench.bench.leaderboard.write_leaderboards` to a scratch folder, and compared column
by column with the committed rows (all but ``command`` and ``commit``, which say who wrote them).
A difference means the table no longer shows what the code computes: the failure names the
table and the command that regenerates it.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from fricbench.bench.leaderboard import CSV_COLUMNS, env_file_stem, write_leaderboards
from fricbench.bench.runner import run_benchmark
from fricbench.gym import env_ids, get_spec

LEADERBOARDS = Path(__file__).parents[2] / "leaderboards"
SAMPLE = ("none", "ilc", "kalman")
"""Compensators rerun: the reference, one that rehearses, one observer (none of them fitted,
so the sample stays fast)."""
N_SEEDS = 2
PROVENANCE = ("command", "commit")
TABLES = sorted(p for p in LEADERBOARDS.glob("*.csv") if not p.name.endswith(".failures.csv"))


def _read(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _regenerate(path: Path, rows: list[dict[str, str]]) -> str:
    """How to regenerate a table: the commands its rows record, else its .md's, else make."""
    commands = sorted({r["command"] for r in rows if r.get("command")})
    if not commands:
        md = path.with_suffix(".md")
        lines = md.read_text(encoding="utf-8").splitlines() if md.exists() else []
        commands = [ln.split("`")[1] for ln in lines if ln.startswith("- Made by: `")]
    shown = " ; ".join(f"`{c}`" for c in commands) or "`make bench`"
    return f"regenerate it with {shown} (all tables: `make bench`)"


def _settings(rows: list[dict[str, str]], comp: str, path: Path) -> dict[str, object]:
    kinds = {r.get("compensator_kwargs", "") for r in rows if r["compensator"] == comp}
    if len(kinds) != 1:
        pytest.fail(f"{path.relative_to(LEADERBOARDS.parent)}: `{comp}` rows from runs with "
                    f"different settings {sorted(kinds)}: {_regenerate(path, rows)}")
    kind = kinds.pop()
    return json.loads(kind) if kind else {}


@pytest.mark.parametrize("path", TABLES, ids=[p.stem for p in TABLES])
def test_committed_rows_match_the_code(path: Path, tmp_path: Path) -> None:
    table = path.relative_to(LEADERBOARDS.parent)
    rows = _read(path)
    assert rows, f"{table}: no rows"
    env = rows[0]["env"]
    assert env_file_stem(env) == path.stem, f"{table}: rows of {env}"
    assert env in env_ids(benchmark_only=True), (
        f"{table}: a table of {env}, which is not a registered benchmark env: remove it or "
        f"{_regenerate(path, rows)}")
    seeds = sorted({int(r["seed"]) for r in rows})[:N_SEEDS]
    comps = [c for c in SAMPLE if any(r["compensator"] == c for r in rows)]
    trajs = sorted({r["trajectory"] for r in rows})
    modes = {r["plant"] for r in rows if r["compensator"] in comps}
    assert len(modes) == 1, f"{table}: drawn and nominal plants mixed: {_regenerate(path, rows)}"
    settings = {c: kw for c in comps if (kw := _settings(rows, c, path))}
    records = list(run_benchmark([env], comps, seeds, trajs, n_jobs=1, progress=False,
                                 comp_kwargs=settings, nominal=modes == {"nominal"}))
    write_leaderboards(records, tmp_path, "test", "test",
                       {env: (get_spec(env).description, get_spec(env).fit_on)})
    fresh = {(r["compensator"], r["trajectory"], r["seed"]): r for r in _read(tmp_path / path.name)}
    committed = {(r["compensator"], r["trajectory"], r["seed"]): r for r in rows}
    columns = [c for c in CSV_COLUMNS if c not in PROVENANCE]
    diffs = []
    for key, new in sorted(fresh.items()):
        old = committed.get(key)
        if old is None:
            diffs.append(f"{' '.join(key)}: not in the table")
            continue
        changed = [f"{c} {old.get(c, '')!r} -> {new[c]!r}" for c in columns
                   if old.get(c, "") != new[c]
                   and not (c == "reason" and old["status"] == new["status"] == "failed")]
        if changed:
            diffs.append(f"{' '.join(key)}: {', '.join(changed[:4])}")
    assert not diffs, (
        f"{table}: {len(diffs)} of {len(fresh)} rerun rows ({', '.join(comps)}; seeds "
        f"{seeds}) differ from the committed ones, so the table no longer shows what the code "
        f"computes; {_regenerate(path, rows)}. First: " + "; ".join(diffs[:3]))
