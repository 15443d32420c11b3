"""fricbench train: a tiny run writes a loadable policy that records its command."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from fricbench.compensators import make_compensator
from fricbench.compensators.command import add_parser
from fricbench.compensators.train import train_agent


def test_tiny_ppo_run(tmp_path: Path) -> None:
    res = train_agent("rl-ppo", steps=256, seed=1, out=tmp_path / "tiny",
                      overrides={"n_envs": 2, "n_steps": 64, "batch_size": 64, "n_epochs": 1})
    assert res.json_path == tmp_path / "tiny.json" and res.weights_path.is_file()
    data = json.loads(res.json_path.read_text())
    assert data["training"]["seed"] == 1 and "validation" in data["training"]
    comp = make_compensator("rl-ppo", policy=res.json_path).fit("fricbench/PaperAxis-v0")
    assert comp.policy_.spec.algo == "ppo"


def test_cli_parser() -> None:
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["train", "rl-sac", "--steps", "10", "--seed", "3"])
    assert args.compensator == "rl-sac" and args.steps == 10 and args.seed == 3
    assert args.env == "fricbench/RandomFriction-v0"
