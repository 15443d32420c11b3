"""fricbench train: a tiny run writes a loadable policy that records its command; the default
output is a new file in the current directory and nothing is overwritten without --force."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import pytest
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

from fricbench.cli import main
from fricbench.compensators import make_compensator, train
from fricbench.compensators.command import add_parser
from fricbench.compensators.train import TrainResult, make_training_env, train_agent
from fricbench.gym.sb3 import SB3VecEnv


def test_tiny_ppo_run(tmp_path: Path) -> None:
    res = train_agent("rl-ppo", steps=256, seed=1, out=tmp_path / "tiny",
                      overrides={"n_envs": 2, "n_steps": 64, "batch_size": 64, "n_epochs": 1,
                                 "reference_pool": 2})
    assert res.json_path == tmp_path / "tiny.json" and res.weights_path.is_file()
    data = json.loads(res.json_path.read_text())
    assert data["training"]["seed"] == 1 and "validation" in data["training"]
    assert data["training"]["vec_env"] == "native"
    assert data["training"]["n_envs"] == 2 and data["training"]["reference_pool"] == 2
    assert "reference_pool" not in data["training"]["hyperparameters"]
    assert " --vec-env native " in data["training"]["command"]
    comp = make_compensator("rl-ppo", policy=res.json_path).fit("fricbench/PaperAxis-v0")
    assert comp.policy_.spec.algo == "ppo"


def test_cli_parser() -> None:
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["train", "rl-sac", "--steps", "10", "--seed", "3"])
    assert args.compensator == "rl-sac" and args.steps == 10 and args.seed == 3
    assert args.env == "fricbench/RandomFriction-v0" and args.vec_env == "native"
    args = parser.parse_args(["train", "rl-ppo", "--vec-env", "dummy"])
    assert args.vec_env == "dummy"
    with pytest.raises(SystemExit):
        parser.parse_args(["train", "rl-ppo", "--vec-env", "subproc"])


def test_training_env_is_the_native_vector_env_or_a_dummy_vec_env() -> None:
    native = make_training_env("fricbench/PaperAxis-v0", n_envs=3, seed=0, reference_pool=1)
    assert isinstance(native, VecMonitor) and isinstance(native.venv, SB3VecEnv)
    assert native.num_envs == 3
    dummy = make_training_env("fricbench/PaperAxis-v0", n_envs=2, seed=0, vec_env="dummy")
    assert isinstance(dummy, DummyVecEnv) and dummy.num_envs == 2
    assert dummy.observation_space == native.observation_space
    with pytest.raises(ValueError, match="vec_env='subproc'"):
        make_training_env("fricbench/PaperAxis-v0", n_envs=2, seed=0, vec_env="subproc")


class _Trained(Exception):
    """Raised instead of training: the command got past its checks."""


@pytest.fixture
def no_training(monkeypatch: pytest.MonkeyPatch) -> None:
    def make_training_env(*args: object, **kwargs: object) -> None:
        raise _Trained

    monkeypatch.setattr(train, "make_training_env", make_training_env)


@pytest.mark.parametrize("existing", [".json", ".pt"])
def test_cli_refuses_to_overwrite(existing: str, tmp_path: Path, no_training: None,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / f"mine{existing}"
    path.write_text("shipped")
    assert main(["train", "rl-sac", "--out", str(tmp_path / "mine")]) == 2
    err = capsys.readouterr().err
    assert f"fricbench train: error: {path} exists; pass --force" in err
    assert path.read_text() == "shipped"


def test_cli_force_overwrites(tmp_path: Path, no_training: None) -> None:
    (tmp_path / "mine.json").write_text("shipped")
    with pytest.raises(_Trained):  # past the check, into training
        main(["train", "rl-sac", "--out", str(tmp_path / "mine"), "--force"])


def test_cli_default_out_is_new_in_current_directory(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    shipped = tmp_path / "fricbench" / "policies" / "rl-sac.json"  # run from the checkout
    shipped.parent.mkdir(parents=True)
    shipped.write_text("shipped")
    monkeypatch.chdir(tmp_path)
    calls: list[dict[str, Any]] = []

    def fake_train(comp_id: str, **kwargs: Any) -> TrainResult:
        calls.append(kwargs)
        return TrainResult(Path("x.json"), Path("x.pt"), 0.0,
                           {"policy_max_um": 1.0, "none_max_um": 2.0, "improvement_pct": 50.0})

    monkeypatch.setattr(train, "train_agent", fake_train)
    assert main(["train", "rl-sac", "--seed", "3"]) == 0
    assert main(["train", "rl-sac", "--seed", "3", "--vec-env", "dummy"]) == 0
    kwargs, dummy = calls
    assert Path(kwargs["out"]) == Path("policies/rl-sac-seed3")
    assert kwargs["command"].endswith("--seed 3 --out policies/rl-sac-seed3")
    assert kwargs["vec_env"] == "native" and dummy["vec_env"] == "dummy"
    assert "--vec-env dummy" in dummy["command"]
    assert shipped.read_text() == "shipped"


def test_train_agent_raises_before_training(tmp_path: Path, no_training: None) -> None:
    (tmp_path / "rl-ppo.pt").write_text("shipped")
    with pytest.raises(FileExistsError) as exc:
        train_agent("rl-ppo", steps=256, out=tmp_path)  # a folder: <folder>/rl-ppo.*
    assert exc.value.filename == str(tmp_path / "rl-ppo.pt")


@pytest.mark.parametrize("env_id", ["fricbench/EMPS-v0", "fricbench/PaperAxis-v0"])
def test_cli_refuses_an_env_of_scored_references(env_id: str, tmp_path: Path, no_training: None,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Its fixed references are the benchmark's evaluation set: never trained on."""
    assert main(["train", "rl-residual", "--env", env_id, "--out", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err
    assert f"env_id='{env_id}': its references (m_serial, " in err
    assert "Traceback" not in err and not list(tmp_path.iterdir())
