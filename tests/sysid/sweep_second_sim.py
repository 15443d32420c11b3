"""Sweep ``fricbench diagnose`` over random runs of the second simulator (a script, not a test).

``python tests/sysid/sweep_second_sim.py [--seeds 1-7] [--kinds control,backlash]
[--duration S] [--keep DIR]`` draws one case per kind and seed (:func:`second_sim.draw_case`:
the controller, delay, saturation, units, logging rate, effort and CSV layout are drawn with
the physics), writes it as a CSV, runs the real command line on it in-process with ``--json``
and prints one row per case: the variant, the effect present and those named, the position
rms before -> after against the case's noise floor, the verdict (when the report has one),
whether the diagnosis is right (:mod:`second_sim_check`), why not, and the time the command
took. The default, 6 kinds x seeds 1..7, is 42 cases; the count of right ones, per logging rate
and in all, ends the output and the exit status is 1 when one is wrong.

Run it with ``PYTHONPATH`` holding the repository (``PYTHONPATH=. python
tests/sysid/sweep_second_sim.py``); pytest does not collect it (not a ``test_*.py`` file).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

# first: fricbench pins numpy's CPU dispatch before numpy loads
import fricbench  # noqa: E402,F401

# isort: split
import second_sim as S  # noqa: E402
import second_sim_check as C  # noqa: E402


def _seeds(text: str) -> list[int]:
    """``"3"``, ``"1-7"`` or ``"1-3,9"`` as a list of seeds."""
    seeds: list[int] = []
    for part in text.split(","):
        first, _, last = part.strip().partition("-")
        seeds.extend(range(int(first), int(last or first) + 1))
    return seeds


def main(argv: list[str] | None = None) -> int:
    """Run the sweep; exit status 1 when a case is not diagnosed right."""
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--seeds", default="1-7", help="seeds: 'a-b', 'a' or a comma list of "
                                                   "those (default: 1-7)")
    ap.add_argument("--kinds", default=",".join(S.KINDS),
                    help=f"comma-separated kinds among {','.join(S.KINDS)} (default: all)")
    ap.add_argument("--cases", default=None, metavar="KIND/SEED,...",
                    help="only these cases, e.g. 'thermal/18,backlash/2' (instead of --seeds "
                         "and --kinds)")
    ap.add_argument("--duration", type=float, default=None,
                    help="run length, s (default: drawn per case in 8..16 s)")
    ap.add_argument("--keep", metavar="DIR", default=None,
                    help="write the CSV and JSON files here and keep them")
    args = ap.parse_args(argv)
    kinds = [k for k in args.kinds.split(",") if k]
    unknown = set(kinds) - set(S.KINDS)
    if unknown:
        ap.error(f"--kinds: unknown {','.join(sorted(unknown))}; expected {','.join(S.KINDS)}")
    pairs = [(seed, kind) for seed in _seeds(args.seeds) for kind in kinds]
    if args.cases:
        pairs = []
        for item in args.cases.split(","):
            kind, _, seed = item.strip().partition("/")
            if kind not in S.KINDS or not seed.isdigit():
                ap.error(f"--cases: {item!r}: expected KIND/SEED with KIND among "
                         f"{','.join(S.KINDS)}")
            pairs.append((int(seed), kind))
    tmp = None
    if args.keep:
        os.makedirs(args.keep, exist_ok=True)
        workdir = args.keep
    else:
        tmp = tempfile.TemporaryDirectory(prefix="sweep-second-sim-")
        workdir = tmp.name
    print(C.HEADER + "   sim", flush=True)
    outcomes = []
    t_all = time.perf_counter()
    try:
        for seed, kind in pairs:
            t0 = time.perf_counter()
            case = S.draw_case(kind, seed, duration=args.duration)
            t_sim = time.perf_counter() - t0
            outcome = C.diagnose_case(case, workdir)
            outcomes.append(outcome)
            print(f"{C.format_row(outcome)}   [sim {t_sim:.1f}s]", flush=True)
    finally:
        if tmp is not None:
            tmp.cleanup()
    n_ok = sum(o.ok for o in outcomes)
    controls = [o for o in outcomes if o.case.kind == "control"]
    false_in_controls = sum(bool(set(o.effects) - S.FRICTION_NAMES) for o in controls)
    times = [o.elapsed for o in outcomes]
    n_nulls = sum(o.wrong_only_by_candidate_nulls for o in outcomes)
    # by logging rate: a log slower than the drive's loop is the hardest part of the sweep
    rates = sorted({o.case.variant.log_every for o in outcomes})
    by_rate = ", ".join(
        f"logged every {k} loop period{'s' if k > 1 else ''}: "
        f"{sum(o.ok for o in outcomes if o.case.variant.log_every == k)}/"
        f"{sum(o.case.variant.log_every == k for o in outcomes)}" for k in rates)
    print(f"by rate: {by_rate}")
    print(f"{n_ok}/{len(outcomes)} right ({n_ok + n_nulls} if the nulls inside candidate lists "
          f"were not counted); controls with a false effect: {false_in_controls}/"
          f"{len(controls)}; diagnose time per case: mean {sum(times) / max(len(times), 1):.1f}"
          f" s, max {max(times, default=0.0):.1f} s; total {time.perf_counter() - t_all:.0f} s")
    return 0 if n_ok == len(outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
