"""Wider randomized sweep of the undeclared-effect cases (a script, not a test).

``python tests/sysid/sweep_undeclared.py [--seeds 11-16] [--kinds cogging,backlash]`` runs
:func:`test_diagnose_undeclared.check_case` on every kind and seed and prints one line per
case and the number that pass. The default, 5 kinds x seeds 11..16, is 30 cases (about two
minutes on one core).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

# first: fricbench pins numpy's CPU dispatch before numpy loads
import fricbench  # noqa: E402,F401

# isort: split
from test_diagnose_undeclared import check_case  # noqa: E402

KINDS = ("control", "cogging", "backlash", "thermal", "posdep")


def main() -> int:
    """Run the sweep; exit status 1 when a case fails."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="11-16", help="first-last seed (default: 11-16)")
    ap.add_argument("--kinds", default=",".join(KINDS), help="comma-separated kinds")
    args = ap.parse_args()
    first, _, last = args.seeds.partition("-")
    seeds = range(int(first), int(last or first) + 1)
    kinds = [k for k in args.kinds.split(",") if k]
    n_ok = n = 0
    for kind in kinds:
        for seed in seeds:
            t0 = time.perf_counter()
            failures, out = check_case(kind, seed)
            n += 1
            n_ok += not failures
            pos = out["position"]
            print(f"{kind:8s} {seed:3d} {'ok  ' if not failures else 'FAIL'} "
                  f"{','.join(out['effects']) or '-':45s} rms {pos['rms_before']:.3g} -> "
                  f"{pos['rms_after']:.3g} m  {time.perf_counter() - t0:.1f} s"
                  + ("" if not failures else "  " + "; ".join(failures)), flush=True)
    print(f"{n_ok}/{n} cases pass")
    return 0 if n_ok == n else 1


if __name__ == "__main__":
    sys.exit(main())
