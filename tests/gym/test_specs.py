"""Env specs: a malformed spec on FRICBENCH_ENV_PATH is skipped with one warning naming file and
key, the shipped envs keep working, ``fricbench list --check`` reports it; valid specs load as
before."""

from __future__ import annotations

import os
import sys
import tomllib
import warnings
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import pytest

from fricbench.axis import Axis
from fricbench.bench.runner import plan_benchmark
from fricbench.cli import main
from fricbench.gym import EnvSpecWarning, check_specs, env_ids, env_registry, register_envs, specs
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
    monkeypatch.setattr(env_registry, "_entries", dict(env_registry._entries))
    monkeypatch.setattr(env_registry, "_files_read", set(env_registry._files_read))
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


def test_a_user_namespace_is_registered(tmp_path: Path,
                                       monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "mill.toml").write_text('id = "local/MyMill-v0"\n[task]\n'
                                        'trajectories = [{ id = "random", duration = 2.0 }]\n')
    monkeypatch.setenv("FRICBENCH_ENV_PATH", str(tmp_path))
    with warnings.catch_warnings():
        warnings.simplefilter("error", EnvSpecWarning)
        ids = register_envs()
    assert "local/MyMill-v0" in ids
    env = gym.make("local/MyMill-v0")
    env.reset(seed=0)
    env.close()


@pytest.mark.parametrize("env_id", ["MyMill-v0", "local/MyMill", "local/sub/MyMill-v0",
                                    "local/My Mill-v0"])
def test_an_id_without_namespace_or_version_is_refused(env_id: str, tmp_path: Path) -> None:
    (tmp_path / "mill.toml").write_text(f'id = "{env_id}"\n')
    with pytest.raises(specs.EnvSpecError, match="expected a string 'namespace/Name-vN'"):
        specs.load_spec(tmp_path / "mill.toml")


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


def _plugin_distribution(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A third-party distribution on sys.path whose ``fricbench.envs`` entry points name a spec
    file, a parsed spec, a function that registers one, a malformed spec and a missing name."""
    for name, body in (("a", ""), ("b", 'description = "parsed"\n'),
                       ("c", 'fit_on = "fricbench/PaperAxis-v0"\n'), ("bad", "[task\n")):
        (tmp_path / f"{name}.toml").write_text(
            f'id = "fricbench/Plugin{name.upper()}-v0"\n{body}'
            '[task]\ntrajectories = [{ id = "random", duration = 2.0 }]\n')
    (tmp_path / "fb_env_plugin_demo.py").write_text(
        "from pathlib import Path\n"
        "from fricbench.gym import specs\n"
        "HERE = Path(__file__).parent\n"
        "A = HERE / 'a.toml'\n"
        "B = specs.load_spec(HERE / 'b.toml')\n"
        "BAD = str(HERE / 'bad.toml')\n"
        "def register(registry):\n"
        "    registry.register_spec(str(HERE / 'c.toml'))\n")
    dist = tmp_path / "fb_env_plugin_demo-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: fb-env-plugin-demo\n"
                                   "Version: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "[fricbench.envs]\na = fb_env_plugin_demo:A\nb = fb_env_plugin_demo:B\n"
        "c = fb_env_plugin_demo:register\nbad = fb_env_plugin_demo:BAD\n"
        "gone = fb_env_plugin_demo:Missing\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(env_registry, "_plugins_loaded", False)


def test_plugin_env_specs_through_the_entry_point_group(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    _plugin_distribution(tmp_path, monkeypatch)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ids = env_registry.ids()
    finally:
        sys.modules.pop("fb_env_plugin_demo", None)
    messages = sorted(str(w.message) for w in caught if issubclass(w.category, EnvSpecWarning))
    assert len(messages) == 2, messages
    assert messages[0].startswith(f"{tmp_path / 'bad.toml'}: invalid TOML"), messages
    assert "'gone'" in messages[1] and "Missing" in messages[1], messages
    plugged = ["fricbench/PluginA-v0", "fricbench/PluginB-v0", "fricbench/PluginC-v0"]
    assert set(plugged) <= set(ids) and set(SHIPPED) <= set(ids)
    assert "fricbench/PluginBAD-v0" not in ids
    assert env_registry.spec("fricbench/PluginB-v0").description == "parsed"
    assert env_ids() == ids and register_envs() == ids
    for env_id in plugged:  # what a shipped env does: gym.make, the registry's make, the bench
        env = gym.make(env_id)
        env.reset(seed=0)
        env.close()
        assert type(env_registry.make(env_id)).__name__ == "ServoAxisEnv"
    assert len(plan_benchmark(plugged, ["none"], [0])) == 3
    assert main(["list"]) == 0
    rows = [ln.split(maxsplit=2) for ln in capsys.readouterr().out.splitlines()]
    assert ["fricbench/PluginB-v0", str(tmp_path / "b.toml"), "parsed"] in rows


def test_env_registry_takes_specs_only() -> None:
    spec = env_registry.spec("fricbench/PaperAxis-v0").data
    with pytest.raises(TypeError, match="register_spec"):
        env_registry.register("fricbench/Other-v0", "fricbench.gym.specs:make_env")
    with pytest.raises(TypeError, match="expected a spec file's path or an EnvSpecFile"):
        env_registry.register_spec(5)  # type: ignore[arg-type]
    assert env_registry.register_spec(spec) == spec.id  # the same file again: nothing to do
    with pytest.raises(ValueError, match="already defined by"):
        env_registry.register_spec(replace(spec, path="elsewhere.toml"))


def test_a_missing_env_path_folder_is_reported(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    missing, a_file = tmp_path / "nowhere", tmp_path / "a.toml"
    a_file.write_text("")
    monkeypatch.delenv("FRICBENCH_ENV_PATH", raising=False)
    # what this process has registered already (the shipped specs, and a user's spec another
    # test of the same worker may have loaded): nothing is added from the bad entries
    before = set(register_envs())
    assert set(SHIPPED) <= before
    monkeypatch.setenv("FRICBENCH_ENV_PATH", f"{missing}{os.pathsep}{a_file}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert set(register_envs()) == before
    messages = [str(w.message) for w in caught if issubclass(w.category, EnvSpecWarning)]
    assert f"FRICBENCH_ENV_PATH: {missing} does not exist; no env specs read from it" in messages
    assert f"FRICBENCH_ENV_PATH: {a_file} is not a folder; no env specs read from it" in messages
