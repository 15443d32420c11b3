"""Env specs: a malformed spec on FRICBENCH_ENV_PATH is skipped with one warning naming file and
key, the shipped envs keep working, ``fricbench list --check`` reports it; valid specs load as
before."""

from __future__ import annotations

import tomllib
import warnings
from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import pytest

from fricbench.axis import Axis
from fricbench.cli import main
from fricbench.gym import EnvSpecWarning, check_specs, env_ids, register_envs, specs
from fricbench.gym.task import TaskConfig

SHIPPED = env_ids()
HEAD = 'id = "fricbench/Malformed-v0"\n'

# case id, {file name: content}, the bad file, the key named, what the message says
CORPUS: list[tuple[str, dict[str, str | bytes], str, str, str]] = [
    ("toml-syntax", {"bad.toml": HEAD + "[task\n"}, "bad.toml", "line 2", "invalid TOML"),
    ("deep-nesting", {"bad.toml": HEAD + "[task]\ntrajectories = " + "[" * 5000 + "]" * 5000},
     "bad.toml", "key 'trajectories'", "nested too deeply"),
    ("not-utf8", {"bad.toml": b'id = "fricbench/Malformed-v0"\n# \xff\xfe\n'}, "bad.toml",
     "byte", "not UTF-8"),
    ("randomize-array", {"bad.toml": HEAD + "[task]\nrandomize = [1, 2]\n"}, "bad.toml",
     "task.randomize=[1, 2]", "expected a table"),
    ("friction-string", {"bad.toml": HEAD + '[axis]\nfriction = "stribeck"\n'}, "bad.toml",
     "axis.friction='stribeck'", "expected a table"),
    ("duplicate-of-shipped", {"bad.toml": 'id = "fricbench/PaperAxis-v0"\n'}, "bad.toml",
     "id='fricbench/PaperAxis-v0'", "already defined by"),
    ("duplicate-of-user", {"a.toml": HEAD, "b.toml": HEAD}, "b.toml",
     "id='fricbench/Malformed-v0'", "a.toml"),
    ("id-number", {"bad.toml": "id = 5\n"}, "bad.toml", "id=5", "expected a string"),
    ("number-as-string", {"bad.toml": HEAD + '[axis.controller]\nkp = "fast"\n'}, "bad.toml",
     "axis.controller.kp='fast'", "expected a number"),
    ("string-as-number", {"bad.toml": HEAD + "[axis.effects]\nmeasurement = 3\n"}, "bad.toml",
     "axis.effects.measurement=3", "expected a string"),
    ("integer-overflow", {"bad.toml": HEAD + "[axis.mechanics]\nmass = " + "9" * 400 + "\n"},
     "bad.toml", "axis.mechanics.mass=", "expected a number"),
    ("nested-table-as-number",
     {"bad.toml": HEAD + "[task.reward]\nerror_scale = " + "{ a = " * 50 + "1" + " }" * 50},
     "bad.toml", "task.reward.error_scale=", "expected a number"),
    ("bad-value", {"bad.toml": HEAD + "[axis.mechanics]\nmass = -1.0\n"}, "bad.toml",
     "axis.mechanics.mass=-1.0", "expected > 0"),
    ("unstable-loop", {"bad.toml": HEAD + "[axis.controller]\nkp = 1e6\n"}, "bad.toml",
     "axis.controller.kp=1e+06 1/s", "the sampled closed loop is unstable"),
    ("unknown-top-key", {"bad.toml": HEAD + 'descripton = "x"\n'}, "bad.toml", "descripton",
     "did you mean 'description'"),
    ("unknown-axis-section", {"bad.toml": HEAD + "[axis.controler]\nkp = 100.0\n"}, "bad.toml",
     "axis.controler", "did you mean 'controller'"),
    ("unknown-parameter", {"bad.toml": HEAD + "[axis.controller]\nkpp = 100.0\n"}, "bad.toml",
     "axis.controller.kpp", "did you mean 'kp'"),
    ("unknown-friction-id", {"bad.toml": HEAD + '[axis.friction]\nid = "stribek"\n'},
     "bad.toml", "axis.friction.id='stribek'", "did you mean 'stribeck'"),
    ("trajectories-string", {"bad.toml": HEAD + '[task]\ntrajectories = "m_serial"\n'},
     "bad.toml", "task.trajectories='m_serial'", "expected an array"),
    ("trajectory-unknown-id",
     {"bad.toml": HEAD + '[task]\ntrajectories = ["m_serial", "m_serail"]\n'}, "bad.toml",
     "task.trajectories[1]", "did you mean 'm_serial'"),
    ("trajectory-bad-parameter",
     {"bad.toml": HEAD + '[task]\ntrajectories = [{ id = "curve", duration = -1.0 }]\n'},
     "bad.toml", "task.trajectories[0].duration=-1.0", "expected > 0"),
    ("trajectory-unknown-parameter",
     {"bad.toml": HEAD + '[task]\ntrajectories = [{ id = "random", duraton = 5.0 }]\n'},
     "bad.toml", "task.trajectories[0].duraton", "did you mean 'duration'"),
    ("trajectory-ts", {"bad.toml": HEAD + '[task]\ntrajectories = [{ id = "s_curve", ts = 0.01 }]'},
     "bad.toml", "task.trajectories[0].ts", "axis.controller.ts"),
    ("trajectory-too-long",
     {"bad.toml": HEAD + '[task]\ntrajectories = [{ id = "random", duration = 1e9 }]\n'},
     "bad.toml", "task.trajectories[0].duration=1000000000.0", "MAX_REFERENCE_SAMPLES"),
    ("trajectory-set-too-long",
     {"bad.toml": HEAD + '[task]\ntrajectories = [{ id = "curve", duration = 600.0 }, '
                         '{ id = "curve", duration = 601.0 }]\n'},
     "bad.toml", "task.trajectories:", "MAX_REFERENCE_SAMPLES"),
    ("trajectory-axes-mixed", {"bad.toml": HEAD + '[task]\ntrajectories = ["s_curve", "circle"]'},
     "bad.toml", "task.trajectories[1]", "2-axis trajectory"),
    ("randomize-unknown-key", {"bad.toml": HEAD + "[task.randomize]\nfcc = [200.0, 400.0]\n"},
     "bad.toml", "task.randomize.fcc", "did you mean 'fc'"),
    ("randomize-reversed-range", {"bad.toml": HEAD + "[task.randomize]\nfc = [400.0, 200.0]\n"},
     "bad.toml", "task.randomize.fc=[400.0, 200.0]", "low <= high"),
    ("randomize-invalid-model", {"bad.toml": HEAD + "[task.randomize]\nfc = [-100.0, 200.0]\n"},
     "bad.toml", "task.randomize", "low ends"),
    ("fit-on-unknown", {"bad.toml": HEAD + 'fit_on = "fricbench/PaperAxs-v0"\n'}, "bad.toml",
     "fit_on='fricbench/PaperAxs-v0'", "did you mean 'fricbench/PaperAxis-v0'"),
    ("benchmark-string", {"bad.toml": HEAD + 'benchmark = "false"\n'}, "bad.toml",
     "benchmark='false'", "TOML boolean"),
]


@pytest.fixture(autouse=True)
def _restore_registries(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Each case starts from the shipped envs and leaves nothing registered behind."""
    monkeypatch.setattr(specs, "_SPECS", dict(specs._SPECS))
    monkeypatch.setattr(specs, "_SEEN", set(specs._SEEN))
    before = set(gym.registry)
    yield
    for env_id in set(gym.registry) - before:
        del gym.registry[env_id]


@pytest.mark.parametrize(("files", "bad", "key", "problem"),
                         [pytest.param(*case[1:], id=case[0]) for case in CORPUS])
def test_malformed_spec_is_skipped_and_reported(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        files: dict[str, str | bytes], bad: str, key: str, problem: str) -> None:
    for name, content in files.items():
        (tmp_path / name).write_bytes(content if isinstance(content, bytes) else content.encode())
    monkeypatch.setenv("FRICBENCH_ENV_PATH", str(tmp_path))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ids = register_envs()
    messages = [str(w.message) for w in caught if issubclass(w.category, EnvSpecWarning)]
    assert len(messages) == 1, messages
    assert messages[0].startswith(f"{tmp_path / bad}: ")
    assert key in messages[0] and problem in messages[0], messages[0]
    assert set(SHIPPED) <= set(ids)
    gym.make("fricbench/PaperAxis-v0").close()

    assert main(["list", "--check"]) == 1
    out = capsys.readouterr().out
    reported = [line for line in out.splitlines() if line.startswith(f"  {tmp_path / bad}: ")]
    assert any(key in line and problem in line for line in reported), out


def test_good_user_spec_next_to_a_bad_one_is_registered(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "bad.toml").write_text(HEAD + 'benchmark = "false"\n')
    (tmp_path / "good.toml").write_text('id = "fricbench/GoodUser-v0"\n[task]\n'
                                        'trajectories = [{ id = "random", duration = 2.0 }]\n')
    monkeypatch.setenv("FRICBENCH_ENV_PATH", str(tmp_path))
    with pytest.warns(EnvSpecWarning, match="bad.toml"):
        ids = register_envs()
    assert "fricbench/GoodUser-v0" in ids and "fricbench/Malformed-v0" not in ids
    env = gym.make("fricbench/GoodUser-v0")
    env.reset(seed=0)
    env.close()


def test_shipped_specs_pass_every_check(monkeypatch: pytest.MonkeyPatch,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("FRICBENCH_ENV_PATH", raising=False)
    assert check_specs() == []
    assert main(["list", "--check"]) == 0
    assert "0 problems" in capsys.readouterr().out


@pytest.mark.parametrize("path", specs._shipped_files(), ids=lambda p: p.name)
def test_shipped_specs_load_as_before(path: Path) -> None:
    raw = tomllib.loads(path.read_text(encoding="utf-8"))
    spec = specs.load_spec(path)
    assert spec.axis == Axis.from_dict(raw.get("axis", {}))
    assert spec.task == TaskConfig.from_dict(raw.get("task", {}))
    assert (spec.id, spec.description, spec.benchmark, spec.fit_on) == (
        raw["id"], raw.get("description", ""), raw.get("benchmark", True),
        raw.get("fit_on", raw["id"]))
