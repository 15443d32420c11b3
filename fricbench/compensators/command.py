"""``fricbench train``: train an RL compensator's policy (plugged into :mod:`fricbench.cli`)."""

from __future__ import annotations

import argparse
import shlex
import sys
from typing import Any

__all__ = ["add_parser", "run"]


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``train`` subcommand to ``subparsers`` (from ``add_subparsers``)."""
    from fricbench.compensators.train import ALGOS, VEC_ENVS

    p = subparsers.add_parser(
        "train", help="train an RL compensator's policy (weights + JSON)",
        description="Train a stable-baselines3 agent on a training env and write the "
                    "deterministic actor as <out>.pt (weights) + <out>.json (spec, command). "
                    "Existing files are never replaced without --force (exit 2, checked "
                    "before training).")
    p.add_argument("compensator", choices=sorted(ALGOS), help="compensator id")
    p.add_argument("--algo", choices=("sac", "ppo"), default=None,
                   help=f"rl-residual's algorithm (default: {ALGOS['rl-residual']}); the "
                        "other ids name theirs")
    p.add_argument("--env", default="fricbench/RandomFriction-v0",
                   help="training env id (default: %(default)s)")
    p.add_argument("--vec-env", choices=VEC_ENVS, default="native",
                   help="native: fricbench's vector env, all sub-envs in one compiled step; "
                        "dummy: stable-baselines3's DummyVecEnv of scalar envs, how the "
                        "shipped policies were trained (default: %(default)s)")
    p.add_argument("--steps", type=int, default=200_000,
                   help="environment steps (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the agent, the env resets and the training references "
                        "(default: %(default)s)")
    p.add_argument("--out", default=None, metavar="STEM",
                   help="write STEM.json and STEM.pt (default: policies/<id>-seed<seed> in "
                        "the current directory)")
    p.add_argument("--force", action="store_true",
                   help="overwrite existing policy files at --out")
    p.add_argument("--verbose", type=int, default=0, help="stable-baselines3 verbosity")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Run ``fricbench train`` with parsed ``args``; print where the policy went."""
    from fricbench.compensators.train import default_out, train_agent

    out = args.out or str(default_out(args.compensator, args.seed))
    algo = ["--algo", args.algo] if args.algo is not None else []
    argv = ["fricbench", "train", args.compensator, *algo, "--env", args.env, "--vec-env",
            args.vec_env, "--steps", str(args.steps), "--seed", str(args.seed), "--out", str(out)]
    try:
        res = train_agent(args.compensator, env_id=args.env, steps=args.steps, seed=args.seed,
                          out=out, command=shlex.join(argv), verbose=args.verbose,
                          overwrite=args.force, vec_env=args.vec_env, algo=args.algo)
    except FileExistsError as exc:
        print(f"fricbench train: error: {exc.filename} exists; pass --force to overwrite it, "
              "or --out to write elsewhere", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"fricbench train: error: {exc}", file=sys.stderr)
        return 2
    val = res.validation
    print(f"wrote {res.json_path} and {res.weights_path} ({res.seconds:.0f} s training); "
          f"validation on fresh training references: max |e| {val['policy_max_um']:.2f} um "
          f"vs {val['none_max_um']:.2f} um uncompensated ({val['improvement_pct']:.1f} %)",
          file=sys.stdout)
    return 0
