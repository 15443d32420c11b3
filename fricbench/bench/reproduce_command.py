"""The ``fricbench reproduce [--json OUT.json] [--plots DIR]`` subcommand.

``fricbench.cli`` calls :func:`add_parser` on its sub-parsers and :func:`run` with the parsed
arguments; :func:`main` runs the command on its own
(``python -m fricbench.bench.reproduce_command``). It drives :mod:`fricbench.bench.reproduce`,
so it lives beside it in ``bench/``, above the predictors it compares.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

__all__ = ["add_parser", "run", "main"]

_DESCRIPTION = (
    "Reproduce Wang & Zhang (2023) on the default axis: simulate M-serial and curve runs, "
    "identify the transfer function and the break velocity, extract the friction error, train "
    "TF+LSTM and the other registered predictors, predict held-out runs, pre-compensate, "
    "refit TF+LSTM from further network seeds, and print our numbers beside the paper's, the "
    "targets judged on the median over the seeds."
)


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``reproduce`` sub-command to an ``argparse`` sub-parsers object."""
    p = subparsers.add_parser("reproduce", help="reproduce the paper's TF+LSTM results",
                              description=_DESCRIPTION)
    _add_arguments(p)
    p.set_defaults(func=run)
    return p


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", metavar="OUT.json", default=None,
                   help="write the JSON summary to this file")
    p.add_argument("--plots", metavar="DIR", default=None,
                   help="draw the counterparts of the paper's Figures 11-18 into DIR")
    p.add_argument("--max-epochs", type=int, default=None, metavar="N",
                   help="train the neural predictors for at most N epochs (a quick, less "
                        "accurate run)")
    p.add_argument("--predictors", default=None, metavar="ID,ID,...",
                   help="comma-separated predictor ids to compare (tf and tf+lstm are always "
                        "included)")
    p.add_argument("--seeds", type=int, nargs="+", default=None, metavar="SEED",
                   help="network seeds of tf+lstm: the first is the run the tables report, "
                        "tf+lstm is refitted from each other one, and the targets are judged "
                        "on the median over all (default: 0 1 2 3 4; one seed: the single run)")
    p.add_argument("--quiet", action="store_true", help="do not print training progress")


def run(args: argparse.Namespace) -> int:
    """Run ``fricbench reproduce`` with parsed ``args``; return the exit status."""
    from fricbench.bench.reproduce import (
        ReproduceConfig,
        format_report,
        plot_figures,
        reproduce,
        write_json,
    )

    kwargs: dict[str, Any] = {"verbose": not args.quiet}
    if args.max_epochs is not None:
        if args.max_epochs < 1:
            print(f"fricbench reproduce: --max-epochs={args.max_epochs}: expected >= 1",
                  file=sys.stderr)
            return 2
        kwargs["predictor_params"] = {"max_epochs": args.max_epochs}
    if args.seeds is not None:
        kwargs["seeds"] = tuple(args.seeds)
    if args.predictors:
        kwargs["predictors"] = tuple(s.strip() for s in args.predictors.split(",") if s.strip())
    try:
        result = reproduce(ReproduceConfig(**kwargs))
    except (KeyError, ValueError, TypeError) as exc:
        print(f"fricbench reproduce: {exc}", file=sys.stderr)
        return 2
    print(format_report(result))
    if args.json:
        path = write_json(result, args.json)
        print(f"wrote {path}")
    if args.plots:
        paths = plot_figures(result, args.plots)
        print(f"wrote {len(paths)} figures to {args.plots}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Stand-alone entry: ``python -m fricbench.bench.reproduce_command [--json ...]``."""
    parser = argparse.ArgumentParser(prog="fricbench reproduce", description=_DESCRIPTION)
    _add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
