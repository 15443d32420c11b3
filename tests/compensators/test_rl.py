"""RL compensators: safe policy files, exact export, clear errors naming the file."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import torch

from fricbench.compensators import CompensatorError, make_compensator
from fricbench.compensators.rl import shipped_policy
from fricbench.compensators.rl_policy import PolicyMLP, PolicySpec, load_policy, save_policy

ENV = "fricbench/PaperAxis-v0"


class _Evil:
    """Stands for any pickled object (code would run on unpickling)."""


def _write(tmp_path: Path, **changes: object) -> Path:
    spec = PolicySpec(algo="sac", obs_dim=17, act_dim=1, net_arch=(8, 8), activation="relu",
                      squash="tanh", action_mode="force", action_scale=600.0,
                      env_id="fricbench/RandomFriction-v0", weights="p.pt",
                      training={"command": "test"})
    torch.manual_seed(0)
    mlp = PolicyMLP(17, 1, (8, 8), "relu")
    path = tmp_path / "p.json"
    save_policy(path, spec, mlp)
    if changes:
        data = json.loads(path.read_text())
        data.update(changes)
        path.write_text(json.dumps(data))
    return path


def test_roundtrip_matches_torch(tmp_path: Path) -> None:
    path = _write(tmp_path)
    pol = load_policy(path)
    torch.manual_seed(0)
    mlp = PolicyMLP(17, 1, (8, 8), "relu")
    obs = np.random.default_rng(0).standard_normal((5, 17))
    with torch.no_grad():
        ref = torch.tanh(mlp(torch.as_tensor(obs, dtype=torch.float32))).numpy()
    assert np.allclose(pol(obs), ref, atol=1e-6)


def test_fit_with_custom_policy(tmp_path: Path) -> None:
    comp = make_compensator("rl-sac", policy=_write(tmp_path)).fit(ENV)
    assert comp.policy_.spec.net_arch == (8, 8)


@pytest.mark.parametrize("text", ["{not json", "[]", "{}"])
def test_corrupt_json_names_file(tmp_path: Path, text: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(CompensatorError, match="bad.json"):
        make_compensator("rl-sac", policy=path).fit(ENV)


def test_missing_file_names_file(tmp_path: Path) -> None:
    with pytest.raises(CompensatorError, match="nope.json"):
        make_compensator("rl-ppo", policy=tmp_path / "nope.json").fit(ENV)


def test_missing_weights_names_file(tmp_path: Path) -> None:
    path = _write(tmp_path)
    (tmp_path / "p.pt").unlink()
    with pytest.raises(CompensatorError, match="p.pt"):
        make_compensator("rl-sac", policy=path).fit(ENV)


def test_corrupt_weights_names_file(tmp_path: Path) -> None:
    path = _write(tmp_path)
    (tmp_path / "p.pt").write_bytes(b"\x00garbage" * 10)
    with pytest.raises(CompensatorError, match="p.pt"):
        make_compensator("rl-sac", policy=path).fit(ENV)


def test_pickled_object_refused(tmp_path: Path) -> None:
    """A weights file holding arbitrary Python objects is refused (weights_only)."""
    path = _write(tmp_path)
    torch.save({"x": _Evil()}, tmp_path / "p.pt")
    with pytest.raises(CompensatorError, match="p.pt"):
        make_compensator("rl-sac", policy=path).fit(ENV)


def test_mismatched_weights_names_file(tmp_path: Path) -> None:
    path = _write(tmp_path, net_arch=[16, 16])
    with pytest.raises(CompensatorError, match=r"p\.pt.*do not match"):
        make_compensator("rl-sac", policy=path).fit(ENV)


@pytest.mark.parametrize(("field", "value", "match"), [
    ("obs_dim", 35, "obs_dim"),
    ("algo", "ppo", "'ppo' policy"),
    ("action_mode", "offset", "offset"),
    ("format_version", 99, "format_version"),
    ("activation", "gelu", "activation"),
    ("weights", "../p.pt", "weights"),
    ("weights", "..", "weights"),
])
def test_mismatched_spec_names_file(tmp_path: Path, field: str, value: object,
                                    match: str) -> None:
    path = _write(tmp_path, **{field: value})
    with pytest.raises(CompensatorError, match=match) as info:
        make_compensator("rl-sac", policy=path).fit(ENV)
    assert "p.json" in str(info.value) or "p.pt" in str(info.value)


@pytest.mark.parametrize("cid", ["rl-sac", "rl-ppo"])
def test_shipped_policy_records_its_command(cid: str) -> None:
    data = json.loads(shipped_policy(cid).read_text())
    cmd = data["training"]["command"]
    assert cmd.startswith(f"fricbench train {cid} ")
    assert "--steps" in cmd and "--seed" in cmd
    assert data["training"]["steps"] > 0


# -- hostile policy files (issue 14, items 2-3): sizes checked before allocation, every error a
# -- CompensatorError naming the file and the field ----------------------------------------------

def test_integer_weights_refused(tmp_path: Path) -> None:
    path = _write(tmp_path)
    state = torch.load(tmp_path / "p.pt", weights_only=True)
    state["hidden.0.weight"] = (state["hidden.0.weight"] * 10).round().to(torch.int64)
    torch.save(state, tmp_path / "p.pt")
    with pytest.raises(CompensatorError, match=r"p\.pt: tensor 'hidden\.0\.weight' has dtype "
                                               r"torch\.int64; expected a floating dtype"):
        load_policy(path)


def test_deeply_nested_json_refused(tmp_path: Path) -> None:
    path = tmp_path / "deep.json"
    path.write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(CompensatorError, match=r"deep\.json: JSON nested too deeply"):
        load_policy(path)


@pytest.mark.parametrize(("field", "value", "match"), [
    ("activation", ["relu"], r"activation=\['relu'\]: expected one of"),
    ("squash", {"a": 1}, r"squash=\{'a': 1\}: expected one of"),
    ("action_scale", 10**400, r"action_scale=1000.*\.\.\.: expected a positive number"),
    ("obs_mean", [10**400] * 17, r"obs_mean=.*: expected null or a list of 17 finite numbers"),
])
def test_malformed_fields_named(tmp_path: Path, field: str, value: object, match: str) -> None:
    path = _write(tmp_path, **{field: value, "obs_std": [1.0] * 17})
    with pytest.raises(CompensatorError, match=r"p\.json: " + match):
        load_policy(path)


def test_network_size_checked_before_allocation(tmp_path: Path) -> None:
    # 10^12 parameters (4 TB) must be refused from the JSON alone
    path = _write(tmp_path, obs_dim=10**6, net_arch=[10**6])
    with pytest.raises(CompensatorError, match=r"p\.json: obs_dim=1000000, act_dim=1, "
                                               r"net_arch=\[1000000\] declare 1000002000001 "
                                               r"parameters; expected at most 67108864"):
        load_policy(path)


def test_oversized_and_special_files_refused(tmp_path: Path) -> None:
    path = _write(tmp_path)
    with open(tmp_path / "p.pt", "wb") as fh:
        fh.truncate(256 * 2**20 + 1)  # sparse: no disk used
    with pytest.raises(CompensatorError, match=r"p\.pt: 268435457 bytes; expected at most "
                                               r"268435456 bytes"):
        load_policy(path)
    big = tmp_path / "big.json"
    big.write_text(" " * (2**20 + 1))
    with pytest.raises(CompensatorError, match=r"big\.json: 1048577 bytes; expected at most"):
        load_policy(big)
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)  # reading it would wait for a writer forever
    with pytest.raises(CompensatorError, match=r"fifo\.json: not a regular file"):
        load_policy(fifo)
