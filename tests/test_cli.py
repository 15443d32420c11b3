"""The command line: version, list, help texts, simulate, perf keys, bench files, clear errors
and exit codes."""

from __future__ import annotations

import argparse
import csv
import importlib.metadata
import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from fricbench._validation import check_range
from fricbench.bench import runner
from fricbench.cli import _toml_value, build_parser, main
from fricbench.compensators import Compensator, compensator_registry
from fricbench.gym import env_ids
from fricbench.predictors import predictor_registry
from fricbench.trajectories import trajectory_registry


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out == f"fricbench {importlib.metadata.version('fricbench')}\n"


@pytest.fixture
def plugin_predictor() -> Iterator[None]:
    # as a plug-in distribution would register it: no description, a factory from another
    # distribution (scipy), so the docstring and the distribution's name are listed
    predictor_registry.register("test-plugin", "scipy.signal:StateSpace")
    yield
    predictor_registry.unregister("test-plugin")


def test_list(capsys: pytest.CaptureFixture[str], plugin_predictor: None) -> None:
    assert main(["list"]) == 0
    lines = capsys.readouterr().out.splitlines()

    def row(id: str) -> list[str]:
        (line,) = [ln for ln in lines if ln.split()[:1] == [id]]
        return line.split(maxsplit=2)

    # id, the package it comes from, its one-line description (registered, or the docstring's)
    assert row("stribeck") == ["stribeck", "fricbench",
                               "Stribeck friction (the paper's eq. 8) with an optional viscous "
                               "term."]
    assert row("kalman") == ["kalman", "fricbench",
                             "Kalman disturbance observer, estimate fed back as force"]
    assert row("m_serial")[1:] == ["fricbench", "The paper's \"M-serial\" linear test: letters M "
                                                "drawn one after another on one axis."]
    assert row("fricbench/PaperAxis-v0")[1:] == [
        "fricbench", "Paper-calibrated CNC feed axis with Stribeck friction; force compensation."]
    assert row("test-plugin") == ["test-plugin", "scipy",
                                  "Linear Time Invariant system in state-space form."]


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def test_help_texts_speak_to_users() -> None:
    parser = build_parser()
    commands = _subparsers(parser)
    assert set(commands) >= {"list", "simulate", "perf", "bench", "reproduce", "train",
                             "diagnose"}
    for name, sub in [("fricbench", parser), *commands.items()]:
        for action in sub._actions:
            if not isinstance(action, argparse._SubParsersAction):
                assert action.help, f"{name} {action.option_strings or action.dest}: no help"
        text = sub.format_help()
        # no developer talk: module names, glue, issue numbers
        assert not re.search(r"fricbench\.\w|glue|issue|parses arguments", text), (name, text)


def test_simulate_help_lists_valid_values(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    out = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    for id in [*env_ids(), *trajectory_registry.ids()]:
        assert id in out


def test_simulate_writes_csv_and_plot(tmp_path: Path) -> None:
    csv_path, png = tmp_path / "run.csv", tmp_path / "run.png"
    assert main(["simulate", "--env", "fricbench/PaperAxis-v0", "--trajectory", "s_curve",
                 "--csv", str(csv_path), "--plot", str(png)]) == 0
    with csv_path.open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["t", "x_ref", "x", "u [N]"]
    assert len(rows) > 2000
    assert png.stat().st_size > 10_000


def test_simulate_writes_the_ballbar_plot_of_a_circle(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    polar = tmp_path / "ballbar.png"
    assert main(["simulate", "--env", "fricbench/CircleContouring-v0", "--trajectory", "circle",
                 "--polar", str(polar)]) == 0
    assert polar.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "radial error magnified x" in capsys.readouterr().out
    # the circle env's own trajectory is the default
    default = tmp_path / "default.png"
    assert main(["simulate", "--env", "fricbench/CircleContouring-v0", "--polar",
                 str(default)]) == 0
    assert "CircleContouring-v0 / circle" in capsys.readouterr().out and default.is_file()
    other = tmp_path / "no.png"
    assert main(["simulate", "--trajectory", "s_curve", "--polar", str(other)]) == 2
    assert "circle" in capsys.readouterr().err and not other.exists()


def test_unknown_env_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--env", "fricbench/PaperAxs-v0"]) != 0
    assert "did you mean" in capsys.readouterr().err


def test_bench_unknown_compensator(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--compensators", "kalmn"]) != 0
    assert "did you mean 'kalman'" in capsys.readouterr().err


def test_bench_writes_leaderboard(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--envs", "fricbench/PaperAxis-v0", "--compensators", "none",
                 "--trajectories", "s_curve", "--seeds", "0", "--jobs", "1",
                 "--out", str(tmp_path)]) == 0
    assert (tmp_path / "PaperAxis-v0.csv").exists()
    assert (tmp_path / "PaperAxis-v0.md").exists()
    assert (tmp_path / "plots" / "PaperAxis-v0_s_curve.png").exists()
    # the last line: the wall time, the runs, the CPU time per env
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert re.fullmatch(r"bench wall time: \d+ s on 1 job, 1 runs \(0 failed\) \(fits and runs, "
                        r"CPU s: \d+; per env: PaperAxis-v0 \d+\); wrote \d+ files under .*/",
                        last), last


def test_bench_fresh_replaces_the_table_merge_keeps_it(tmp_path: Path) -> None:
    one = ["bench", "--envs", "fricbench/PaperAxis-v0", "--compensators", "none",
           "--trajectories", "s_curve", "--jobs", "1", "--out", str(tmp_path)]
    assert main([*one, "--seeds", "0", "1"]) == 0
    assert main([*one, "--seeds", "1"]) == 0
    with (tmp_path / "PaperAxis-v0.csv").open() as fh:
        assert sorted(r["seed"] for r in csv.DictReader(fh)) == ["0", "1"]  # merged
    assert main([*one, "--seeds", "1", "--fresh"]) == 0
    with (tmp_path / "PaperAxis-v0.csv").open() as fh:
        assert [r["seed"] for r in csv.DictReader(fh)] == ["1"]  # this run's rows alone


@pytest.mark.slow
def test_perf_writes_exactly_the_keys(tmp_path: Path) -> None:
    out = tmp_path / "perf.json"
    assert main(["perf", "--quick", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert set(data) == {"env_steps_per_s", "pendulum_steps_per_s", "vector_env_steps_per_s",
                         "kernel_samples_per_s", "vector_env_to_kernel",
                         "simulate_samples_per_s", "python_control_samples_per_s",
                         "train_steps_per_s", "train_dummy_steps_per_s", "rollout_steps_per_s",
                         "rollout_dummy_steps_per_s", "vector_env_to_simulate"}
    assert all(v > 0 for v in data.values())


class _FitFails(Compensator):
    id: ClassVar[str] = "test-fit-fails"

    def fit(self, env_id: str, *, seed: int = 0) -> Compensator:
        raise RuntimeError("no training data")

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return np.zeros(1)


class _Interrupts(Compensator):
    id: ClassVar[str] = "test-interrupts"

    def _act(self, observation: np.ndarray) -> np.ndarray:
        raise KeyboardInterrupt  # as Ctrl-C would, in the middle of an episode


@pytest.fixture
def test_compensators() -> Iterator[None]:
    for cls in (_FitFails, _Interrupts):
        compensator_registry.register(cls.id, cls)
    yield
    for cls in (_FitFails, _Interrupts):
        compensator_registry.unregister(cls.id)


_ONE_RUN = ["--envs", "fricbench/PaperAxis-v0", "--trajectories", "s_curve", "--seeds", "0",
            "--jobs", "1"]


@pytest.mark.parametrize(("option", "value", "expected"), [
    ("--trajectories", "s_crve", "--trajectories s_crve: unknown trajectory id; did you mean "
                                 "'s_curve'"),
    ("--trajectories", "circle", "--trajectories circle: a 2-axis trajectory; "
                                 "fricbench/PaperAxis-v0 drives 1 axis"),
    ("--envs", "fricbench/PaperAxs-v0", "--envs fricbench/PaperAxs-v0: unknown env id; did you "
                                        "mean 'fricbench/PaperAxis-v0'"),
    ("--compensators", "kalmn", "--compensators kalmn: unknown compensator id; did you mean "
                                "'kalman'"),
    ("--seeds", "-1", "--seeds -1: expected an integer >= 0"),
])
def test_bench_checks_every_id_before_fitting(option: str, value: str, expected: str,
                                               tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    def no_fit(*args: object) -> None:
        raise AssertionError("fitted before checking the arguments")

    monkeypatch.setattr(runner, "fit_compensators", no_fit)
    argv = {"--envs": "fricbench/PaperAxis-v0", "--compensators": "none",
            "--trajectories": "s_curve", "--seeds": "0", option: value}
    assert main(["bench", *(w for kv in argv.items() for w in kv), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


def test_bench_exits_1_when_a_run_failed(tmp_path: Path, test_compensators: None,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", *_ONE_RUN, "--compensators", "test-fit-fails",
                 "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "1 of 1 runs failed" in err and "fit failed: RuntimeError: no training data" in err
    with (tmp_path / "PaperAxis-v0.failures.csv").open() as fh:
        assert [r["compensator"] for r in csv.DictReader(fh)] == ["test-fit-fails"]


def test_bench_ctrl_c_writes_finished_runs_and_exits_130(
        tmp_path: Path, test_compensators: None, capsys: pytest.CaptureFixture[str]) -> None:
    # --jobs 1 runs in this process, in task order: `none` finishes, then the interrupt
    try:
        rc = main(["bench", *_ONE_RUN, "--compensators", "none", "test-interrupts",
                   "--out", str(tmp_path)])
    except KeyboardInterrupt:  # would otherwise stop the whole test session
        pytest.fail("KeyboardInterrupt escaped `fricbench bench`")
    assert rc == 130
    err = capsys.readouterr().err
    assert "interrupted: 1 of 2 runs finished and written; 1 not run:" in err
    assert "fricbench/PaperAxis-v0 test-interrupts s_curve seed 0" in err
    assert "Traceback" not in err
    with (tmp_path / "PaperAxis-v0.csv").open() as fh:
        assert [(r["compensator"], r["status"]) for r in csv.DictReader(fh)] == [("none", "ok")]
    assert not list(tmp_path.glob(".*"))  # no temp file left


def test_bench_keeps_the_finished_runs_when_the_backend_breaks(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A backend raising mid-run (a Ray cluster lost): the finished runs are written, the
    others listed, exit 1, no traceback."""
    real = runner.run_benchmark

    def breaks(*args: object, **kwargs: object) -> Iterator[runner.EpisodeRecord]:
        yield next(iter(real(*args, **kwargs)))  # type: ignore[arg-type]
        raise ConnectionError("lost the cluster")

    monkeypatch.setattr(runner, "run_benchmark", breaks)
    rc = main(["bench", *_ONE_RUN, "--seeds", "0", "1", "--compensators", "none",
               "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 1 and "Traceback" not in err
    assert ("error: the run stopped (ConnectionError: lost the cluster): 1 of 2 runs finished "
            "and written; 1 not run:") in err
    with (tmp_path / "PaperAxis-v0.csv").open() as fh:
        assert [(r["compensator"], r["status"]) for r in csv.DictReader(fh)] == [("none", "ok")]


class _Gain(Compensator):
    """Acts ``gain`` every step (its effort shows the gain it was built with)."""

    id: ClassVar[str] = "test-gain"

    def __init__(self, *, gain: float = 0.0, policy: str = "") -> None:
        super().__init__()
        check_range("gain", gain, -1.0, 1.0)
        self.gain = gain
        self.policy = policy

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return np.full(1, self.gain)


@pytest.fixture
def gain_compensator() -> Iterator[None]:
    compensator_registry.register(_Gain.id, _Gain)
    yield
    compensator_registry.unregister(_Gain.id)


@pytest.mark.parametrize(("text", "value"), [
    ("0.3", 0.3), ("3", 3), ("true", True), ("-1e-4", -1e-4), ('"a b"', "a b"),
    ("[1, 2]", [1, 2]), ("runs/sac/policy.json", "runs/sac/policy.json"), ("sac", "sac"),
    ("1\nx = 2", "1\nx = 2"), ("", ""),
])
def test_compensator_kwargs_values_are_toml(text: str, value: object) -> None:
    assert _toml_value(text) == value and type(_toml_value(text)) is type(value)


@pytest.mark.parametrize(("argv", "expected"), [
    (["--compensator-kwargs", "test-gain-0.5"],
     "--compensator-kwargs test-gain-0.5: expected ID:KEY=VALUE, such as ilc:gain=0.3"),
    (["--compensator-kwargs", "test-gian:gain=0.5"],
     "--compensator-kwargs test-gian: unknown compensator id; did you mean 'test-gain'?"),
    (["--compensator-kwargs", "test-gain:gian=0.5"],
     "--compensator-kwargs test-gain:gian: not a keyword of compensator 'test-gain'; did you "
     "mean 'gain'?; accepted: gain, policy"),
    (["--compensator-kwargs", "test-gain:gain=2"],
     "--compensator-kwargs test-gain: gain=2: expected a value in [-1, 1]"),
    (["--compensator-kwargs", "kalman:gain=0.5"],
     "--compensator-kwargs kalman: settings for a compensator that is not run"),
    (["--compensator-config", "{cfg}"], "--compensator-config {cfg}: gain = 0.5: expected a "
                                        "table"),
    (["--compensator-config", "{missing}"], "--compensator-config {missing}: cannot read"),
    (["--compensator-config", "{typo}"], "--compensator-config {typo} test-gain:gian: not a "
                                         "keyword"),
    (["--compensator-config", "{typo}", "--compensator-kwargs", "test-gain:gian=0.1"],
     "--compensator-kwargs and --compensator-config {typo} test-gain:gian: not a keyword"),
])
def test_bench_checks_compensator_settings_before_fitting(
        argv: list[str], expected: str, tmp_path: Path, gain_compensator: None,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    def no_fit(*args: object) -> None:
        raise AssertionError("fitted before checking the arguments")

    monkeypatch.setattr(runner, "fit_compensators", no_fit)
    files = {"cfg": tmp_path / "cfg.toml", "missing": tmp_path / "missing.toml",
             "typo": tmp_path / "typo.toml"}
    files["cfg"].write_text("gain = 0.5\n")
    files["typo"].write_text("[test-gain]\ngian = 0.5\n")
    names = {k: str(v) for k, v in files.items()}
    out = tmp_path / "out"
    assert main(["bench", *_ONE_RUN, "--compensators", "none", "test-gain", "--out", str(out),
                 *(a.format(**names) for a in argv)]) == 2
    err = capsys.readouterr().err
    assert expected.format(**names) in err and "Traceback" not in err, err
    assert not out.exists()


@pytest.mark.parametrize("case", ["missing", "corrupt", "weights", "other-algo"])
def test_bench_loads_a_policy_file_at_the_option_check(
        case: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A policy named by --compensator-kwargs is loaded before any run: a bad one exits 2
    naming the option and the file, and no compensator ran (none first in the list)."""
    def no_fit(*args: object) -> None:
        raise AssertionError("fitted before checking the policy file")

    monkeypatch.setattr(runner, "fit_compensators", no_fit)
    shipped = Path(runner.__file__).parents[1] / "policies"
    policy = tmp_path / "policy.json"
    if case == "corrupt":
        policy.write_text("{not json")
    elif case == "weights":  # the JSON is fine, its weights file is not there
        policy.write_text((shipped / "rl-sac.json").read_text())
    elif case == "other-algo":  # a PPO policy given to rl-sac
        for suffix in (".json", ".pt"):
            (tmp_path / f"rl-ppo{suffix}").write_bytes((shipped / f"rl-ppo{suffix}").read_bytes())
        policy = tmp_path / "rl-ppo.json"
    out = tmp_path / "out"
    assert main(["bench", *_ONE_RUN, "--compensators", "none", "rl-sac", "--out", str(out),
                 "--compensator-kwargs", f"rl-sac:policy={policy}"]) == 2
    err = capsys.readouterr().err
    assert "error: --compensator-kwargs rl-sac: " in err and "Traceback" not in err, err
    assert str(policy) in err and "(checked on fricbench/PaperAxis-v0)" in err
    assert not out.exists()


def test_bench_records_the_compensator_settings(tmp_path: Path, gain_compensator: None) -> None:
    cfg = tmp_path / "settings.toml"
    cfg.write_text('[test-gain]\ngain = 0.2\npolicy = "from-file"\n')
    assert main(["bench", *_ONE_RUN, "--compensators", "none", "test-gain",
                 "--compensator-config", str(cfg), "--compensator-kwargs", "test-gain:gain=0.5",
                 "--out", str(tmp_path)]) == 0
    with (tmp_path / "PaperAxis-v0.csv").open() as fh:
        rows = {r["compensator"]: r for r in csv.DictReader(fh)}
    # the command line wins key by key; the file's other keys stay
    assert json.loads(rows["test-gain"]["compensator_kwargs"]) == {"gain": 0.5,
                                                                   "policy": "from-file"}
    assert float(rows["test-gain"]["effort_rms"]) == pytest.approx(0.5 * 600.0, rel=1e-3)
    assert rows["none"]["compensator_kwargs"] == ""
    md = (tmp_path / "PaperAxis-v0.md").read_text()
    assert '`test-gain`: `{"gain": 0.5, "policy": "from-file"}`' in md


@pytest.mark.parametrize("option", ["--csv", "--plot", "--polar"])
def test_simulate_refuses_an_existing_output_without_force(
        option: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    import fricbench.axis

    def no_run(*args: object, **kwargs: object) -> None:
        raise AssertionError("simulated before checking the output files")

    monkeypatch.setattr(fricbench.axis, "simulate", no_run)
    out = tmp_path / "keep.out"
    out.write_text("mine")
    argv = ["simulate", "--env", "fricbench/CircleContouring-v0", option, str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{option} {out}: the file exists; pass --force" in err and "Traceback" not in err
    assert out.read_text() == "mine"


def test_simulate_force_overwrites(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    out.write_text("old")
    assert main(["simulate", "--trajectory", "s_curve", "--csv", str(out), "--force"]) == 0
    assert out.read_text().startswith("t,")


@pytest.mark.parametrize("option", ["--json", "--env-out"])
def test_diagnose_refuses_an_existing_output_without_force(
        option: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    import fricbench.sysid.io

    def no_load(*args: object, **kwargs: object) -> None:
        raise AssertionError("read the data before checking the output files")

    monkeypatch.setattr(fricbench.sysid.io, "load_run", no_load)
    data = tmp_path / "run.csv"
    data.write_text("t,x_ref,x,u\n0,0,0,0\n")
    out = tmp_path / ("twin.toml" if option == "--env-out" else "report.json")
    out.write_text("mine")
    assert main(["diagnose", str(data), option, str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{option} {out}: the file exists; pass --force" in err and "Traceback" not in err
    assert out.read_text() == "mine"
    # with --force the option check passes and the run goes on to read the data
    with pytest.raises(AssertionError, match="read the data"):
        main(["diagnose", str(data), option, str(out), "--force"])


@pytest.fixture
def no_diagnosis(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """A data file whose reading fails the test: the options must be refused before it."""
    import fricbench.sysid.io

    def no_load(*args: object, **kwargs: object) -> None:
        raise AssertionError("read the data before checking the options")

    monkeypatch.setattr(fricbench.sysid.io, "load_run", no_load)
    data = tmp_path / "run.csv"
    data.write_text("t,x_ref,x,u\n0,0,0,0\n")
    return data


@pytest.mark.parametrize(("extra", "message"), [
    (["--env-id", "fricbench/PaperAxis-v0"],
     "--env-id fricbench/PaperAxis-v0: already registered (by "),
    (["--env-id", "CartPole-v1"], "--env-id CartPole-v1: expected 'namespace/Name-vN'"),
    (["--env-id", "phys2d/CartPole-v1"],
     "--env-id phys2d/CartPole-v1: already registered (in Gymnasium's registry)"),
    (["--env-out-default"], "default id fricbench/PaperAxis-v0 (from the file name) is already "
                            "registered"),
])
def test_diagnose_refuses_a_taken_twin_id(no_diagnosis: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str],
                                          extra: list[str], message: str) -> None:
    out = tmp_path / "twin.toml"
    if extra == ["--env-out-default"]:
        out, extra = tmp_path / "paper_axis.toml", []
    assert main(["diagnose", str(no_diagnosis), "--env-out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "local/" in err and "Traceback" not in err
    assert not out.exists()


def test_diagnose_takes_a_twin_id_in_the_users_namespace(no_diagnosis: Path,
                                                        tmp_path: Path) -> None:
    with pytest.raises(AssertionError, match="read the data"):  # the options passed
        main(["diagnose", str(no_diagnosis), "--env-out", str(tmp_path / "mill.toml"),
              "--env-id", "local/MyMill-v0"])


@pytest.mark.parametrize(("extra", "expected"), [
    (["--seeds", "0", "3", "0"], "--seeds 0: given twice"),
    (["--seeds", "0", "--compensators", "none", "none"], "--compensators none: given twice"),
    (["--seeds", "0", "--jobs", "0"], "--jobs 0: expected a positive number of processes, or "
                                      "-1 for one per core"),
    (["--seeds", "0", "--jobs", "-2"], "--jobs -2: expected a positive number"),
])
def test_bench_refuses_repeats_and_bad_jobs_before_fitting(
        extra: list[str], expected: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    def no_fit(*args: object) -> None:
        raise AssertionError("fitted before checking the arguments")

    monkeypatch.setattr(runner, "fit_compensators", no_fit)
    argv = ["bench", "--envs", "fricbench/PaperAxis-v0", "--trajectories", "s_curve",
            "--out", str(tmp_path), *extra]
    if "--compensators" not in extra:
        argv += ["--compensators", "none"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


def test_run_benchmark_checks_n_jobs() -> None:
    with pytest.raises(ValueError, match="n_jobs=0: expected a positive number"):
        next(runner.run_benchmark(["fricbench/PaperAxis-v0"], ["none"], [0], n_jobs=0,
                                  progress=False))


@pytest.fixture(scope="module")
def simulated_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("sim") / "run.csv"
    assert main(["simulate", "--trajectory", "s_curve", "--csv", str(path)]) == 0
    return path


def test_simulate_csv_states_its_effort_unit_for_the_loader(simulated_csv: Path) -> None:
    from fricbench.sysid.io import load_run

    run = load_run(simulated_csv)  # the default columns t, x_ref, x, u
    assert run.columns["u"] == "u [N]" and run.u is not None
    assert run.units["effort"] == "N" and run.units["effort_stated"] == "yes"
    with simulated_csv.open() as fh:
        rows = list(csv.DictReader(fh))
    assert np.array_equal(run.u, [float(r["u [N]"]) for r in rows])
    assert np.array_equal(run.x, [float(r["x"]) for r in rows])


def _diagnose_until_the_fit(argv: list[str], monkeypatch: pytest.MonkeyPatch,
                            capsys: pytest.CaptureFixture[str]) -> str:
    """The stderr of ``diagnose`` up to the fit (which is stopped): the loader's warnings."""
    import fricbench.sysid.diagnose.diagnosis as diagnosis

    def stop(*args: object, **kwargs: object) -> None:
        raise ValueError("stopped before the fit")

    monkeypatch.setattr(diagnosis, "diagnose", stop)
    assert main(["diagnose", *argv]) == 1
    err = capsys.readouterr().err
    assert "stopped before the fit" in err
    return err


def test_diagnosing_simulates_csv_takes_its_effort_unit(
        simulated_csv: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    err = _diagnose_until_the_fit([str(simulated_csv)], monkeypatch, capsys)
    assert "--effort-unit" not in err, err
    err = _diagnose_until_the_fit([str(simulated_csv), "--effort-unit", "A"], monkeypatch,
                                  capsys)
    assert "--effort-unit A: column 'u [N]' of " in err and "states N; A is used" in err


@pytest.mark.parametrize(("header", "extra", "message"), [
    ("t [ms],x_ref,x,u", [], "column 't [ms]' states ms; expected a time in s"),
    ("t,x_ref [mm],x [mm],u", [], "column 'x [mm]' states mm but the positions are read "
                                  "in m (--position-unit); expected the same unit, such as "
                                  "--position-unit mm"),
    ("t,x_ref [mm],x [mm],u", ["--position-unit", "um"], "states mm but the positions are "
                                                         "read in um"),
])
def test_a_stated_unit_that_contradicts_the_options_is_refused(
        header: str, extra: list[str], message: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "run.csv"
    rows = [f"{k * 1e-3:g},{np.sin(k / 50):.6g},{np.sin((k - 2) / 50):.6g},{np.cos(k / 7):.4g}"
            for k in range(2000)]
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    assert main(["diagnose", str(path), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_a_large_tracking_error_warning_names_the_file_and_columns(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A warning about the validation run says it is about that file, and what it compares."""
    t = np.arange(2000) * 1e-3
    ref = 0.01 * np.sin(2 * np.pi * t)
    runs = {"measured.csv": ref - 1e-5 * np.cos(2 * np.pi * t),  # tracks
            "validation.csv": 0.4 * ref + 0.004 * np.sin(40 * t)}  # far from its reference
    for name, x in runs.items():
        rows = [f"{a:.6f},{b:.9g},{c:.9g}" for a, b, c in zip(t, ref, x, strict=True)]
        (tmp_path / name).write_text("t,cmd,enc\n" + "\n".join(rows) + "\n")
    err = _diagnose_until_the_fit(
        [str(tmp_path / "measured.csv"), "--validate", str(tmp_path / "validation.csv"),
         "--reference", "cmd", "--position", "enc", "--position-unit", "deg"],
        monkeypatch, capsys)
    hits = [line for line in err.splitlines() if "differs from the reference" in line]
    assert len(hits) == 1, err
    assert hits[0].startswith(f"warning: {tmp_path / 'validation.csv'}: the measured position "
                              "(column 'enc') differs from the reference (column 'cmd') by ")
    assert " deg rms" in hits[0]
