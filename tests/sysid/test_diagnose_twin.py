"""``fricbench diagnose --env-out``: the identified model as a Gymnasium env (issue 13 item 4).

A run of our own simulator with known effects (Stribeck friction and a constant load on the
paper axis) is diagnosed; the twin it writes must load, pass both env checkers and, replayed on
the run's reference (``fricbench simulate --reference-csv``), reproduce the measured position
within 20 % of the diagnosis's own free-run error and far better than the linear model.
"""

from __future__ import annotations

import csv
import json
import os
import tomllib
from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from fricbench.axis import simulate
from fricbench.axis.export import write_csv
from fricbench.axis.plant import PLANT_NAMES
from fricbench.cli import main as cli_main
from fricbench.gym import env_registry, get_spec, register_envs
from fricbench.sysid.diagnose.command import EXIT_BAD_INPUT, EXIT_OK
from fricbench.sysid.diagnose.command import main as diagnose_main
from fricbench.sysid.diagnose.twin import PLANT_PLACES
from fricbench.trajectories import make_trajectory

TWIN_ID = "fricbench/TestTwin-v0"
LOAD_N = 60.0


@pytest.fixture(scope="module")
def twin(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """A simulated run, its diagnosis (JSON) and the twin it wrote."""
    root = tmp_path_factory.mktemp("twin")
    axis = get_spec("fricbench/PaperAxis-v0").axis.with_mechanics(load=LOAD_N)
    run = root / "run.csv"
    write_csv(simulate(axis, make_trajectory("m_serial", ts=1e-3)), str(run))
    folder = root / "envs"
    folder.mkdir()
    out = folder / "twin.toml"
    code = diagnose_main([str(run), "--json", str(root / "diag.json"), "--env-out", str(out),
                          "--env-id", TWIN_ID, "--quiet"])
    assert code == EXIT_OK
    return {"run": run, "folder": folder, "toml": out, "axis": axis,
            "report": json.loads((root / "diag.json").read_text())}


@pytest.fixture
def registered(twin: dict, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """The twin's folder on FRICBENCH_ENV_PATH; nothing left registered afterwards."""
    monkeypatch.setattr(env_registry, "_entries", dict(env_registry._entries))
    monkeypatch.setattr(env_registry, "_files_read", set(env_registry._files_read))
    monkeypatch.setenv("FRICBENCH_ENV_PATH", str(twin["folder"]))
    before = set(gym.registry)
    assert TWIN_ID in register_envs()
    yield TWIN_ID
    for env_id in set(gym.registry) - before:
        del gym.registry[env_id]


def test_twin_runs_under_both_env_checkers(registered: str) -> None:
    env = gym.make(registered)  # wrapped in the passive env checker
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    for _ in range(50):
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        assert np.isfinite(reward) and not terminated
    check_env(env.unwrapped, skip_render_check=True)
    env.close()
    vec = gym.make_vec(registered, num_envs=3, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    vec.step(vec.action_space.sample())
    vec.close()


def test_twin_holds_the_identified_plant_in_si(twin: dict) -> None:
    data = tomllib.loads(twin["toml"].read_text())
    axis = data["axis"]
    assert axis["controller"]["law"] == "linear" and axis["controller"]["kt"] == 1.0
    # the simulated axis: 400 kg, Stribeck fc 350 N / fs 500 N, a 60 N load
    assert abs(axis["mechanics"]["mass"] / 400.0 - 1.0) < 0.1
    assert abs(axis["mechanics"]["load"] / LOAD_N - 1.0) < 0.2
    assert abs(axis["friction"]["fc"] / 350.0 - 1.0) < 0.1
    assert axis["effects"]["quantization"] == pytest.approx(2.5e-7)
    assert "fricbench diagnose" in twin["toml"].read_text().splitlines()[2]
    mode = os.stat(twin["toml"]).st_mode & 0o777
    umask = os.umask(0)
    os.umask(umask)
    assert mode == 0o666 & ~umask


def test_replay_reproduces_the_measured_position(registered: str, twin: dict,
                                                 tmp_path: Path) -> None:
    out = tmp_path / "replay.csv"
    assert cli_main(["simulate", "--env", registered, "--reference-csv", str(twin["run"]),
                     "--position", "x", "--csv", str(out)]) == 0
    with open(twin["run"]) as fh:
        measured = np.array([float(r["x"]) for r in csv.DictReader(fh)])
    with open(out) as fh:
        replay = np.array([float(r["x"]) for r in csv.DictReader(fh)])
    rms = float(np.sqrt(np.mean((replay - measured) ** 2)))
    pos = twin["report"]["position"]
    # measured: 0.25 um against the diagnosis's 0.24 um; the linear model 1.6 um
    assert rms <= 1.2 * pos["rms_after"], (rms, pos)
    assert rms < 0.3 * pos["rms_before"], (rms, pos)


def test_every_plant_column_has_a_place_in_the_env() -> None:
    assert set(PLANT_PLACES) == set(PLANT_NAMES)


@pytest.mark.parametrize(("extra", "message"), [
    (["--env-id", "Twin-v0"], "--env-id Twin-v0: expected 'namespace/Name-vN'"),
    (["--env-id", "fricbench/Twin"], "--env-id fricbench/Twin: expected"),
    (["--env-out-missing"], "the directory"),
    (["--env-out-suffix"], "expected a file name ending in .toml"),
    (["--open-loop", "--effort", "u"], "an open-loop run identifies the plant but no controller"),
    (["--effort-gain", "-3"], "--effort-gain -3: expected a positive number"),
    (["--effort-unit", "V"], "give --effort-gain, the newtons per V"),
])
def test_bad_twin_options(twin: dict, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                          extra: list[str], message: str) -> None:
    out = str(tmp_path / "t.toml")
    if extra == ["--env-out-missing"]:
        out, extra = str(tmp_path / "nowhere" / "t.toml"), []
    elif extra == ["--env-out-suffix"]:
        out, extra = str(tmp_path / "t.txt"), []
    code = diagnose_main([str(twin["run"]), "--env-out", out, "--quiet", *extra])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT, err
    assert message in err and "Traceback" not in err
    assert not os.path.exists(out)


def test_twin_options_need_env_out(twin: dict, capsys: pytest.CaptureFixture[str]) -> None:
    assert diagnose_main([str(twin["run"]), "--env-id", "fricbench/X-v0"]) == EXIT_BAD_INPUT
    assert "--env-id: only with --env-out" in capsys.readouterr().err


@pytest.mark.parametrize(("args", "message"), [
    (["--reference", "q_ref"], "q_ref"),
    (["--position", "q"], "'q'"),
    (["--trajectory", "m_serial"], "give one reference"),
])
def test_bad_replay_options(twin: dict, capsys: pytest.CaptureFixture[str], args: list[str],
                            message: str) -> None:
    code = cli_main(["simulate", "--env", "fricbench/PaperAxis-v0", "--reference-csv",
                     str(twin["run"]), *args])
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err, err


def test_replay_refuses_another_sample_time(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "slow.csv"
    run.write_text("t,x_ref\n" + "".join(f"{0.002 * k},{1e-5 * k}\n" for k in range(200)))
    code = cli_main(["simulate", "--env", "fricbench/PaperAxis-v0", "--reference-csv", str(run)])
    err = capsys.readouterr().err
    assert code == 2 and "sampled every 0.002 s" in err and "ts=0.001 s" in err, err


def test_replay_options_need_a_reference_csv(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["simulate", "--position", "x"]) == 2
    assert "--position x: only with --reference-csv" in capsys.readouterr().err


def _replay(folder: Path, monkeypatch: pytest.MonkeyPatch, env_id: str, run: Path
            ) -> np.ndarray:
    """The position of the twin ``env_id`` (its spec in ``folder``) replaying ``run``'s
    reference (``fricbench simulate --reference-csv``); nothing left registered."""
    monkeypatch.setattr(env_registry, "_entries", dict(env_registry._entries))
    monkeypatch.setattr(env_registry, "_files_read", set(env_registry._files_read))
    monkeypatch.setenv("FRICBENCH_ENV_PATH", str(folder))
    before = set(gym.registry)
    try:
        register_envs()
        replay = folder / "replay.csv"
        assert cli_main(["simulate", "--env", env_id, "--reference-csv", str(run),
                         "--position", "x", "--csv", str(replay)]) == 0
    finally:
        for registered in set(gym.registry) - before:
            del gym.registry[registered]
    with open(replay) as fh:
        return np.array([float(r["x"]) for r in csv.DictReader(fh)])


def test_a_run_without_effort_gives_a_cascade_twin(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """No effort: the model is per unit mass with a fitted cascade; the twin gets --env-mass
    and the env's cascade. Its replay adds the encoder step the diagnosis's free run leaves
    out, so the bound holds the quantisation noise q / sqrt(12) beside the 20 %."""
    axis = get_spec("fricbench/PaperAxis-v0").axis
    run = tmp_path / "run.csv"
    write_csv(simulate(axis, make_trajectory("s_curve", ts=1e-3)), str(run))
    out = tmp_path / "pos.toml"
    assert diagnose_main([str(run), "--no-effort", "--json", str(tmp_path / "d.json"),
                          "--env-out", str(out), "--env-mass", "400", "--quiet"]) == EXIT_OK
    data = tomllib.loads(out.read_text())
    ctrl = data["axis"]["controller"]
    assert ctrl.get("law", "cascade") == "cascade" and ctrl["kp"] > 0 and ctrl["kv"] > 0
    assert data["axis"]["mechanics"]["mass"] == 400.0 and data["id"] == "fricbench/Pos-v0"
    sim = _replay(tmp_path, monkeypatch, "fricbench/Pos-v0", run)
    with open(run) as fh:
        measured = np.array([float(r["x"]) for r in csv.DictReader(fh)])
    rms = float(np.sqrt(np.mean((sim - measured) ** 2)))
    pos = json.loads((tmp_path / "d.json").read_text())["position"]
    q = axis.effects.quantization
    assert rms <= 1.2 * float(np.hypot(pos["rms_after"], q / np.sqrt(12.0))), (rms, pos)
    assert rms < 0.5 * pos["rms_before"], (rms, pos)


def test_a_pid_loop_gives_a_linear_law_twin(tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """A PID drive logged without effort (the second simulator, independent of fricbench):
    the diagnosis models it as a PID position loop, which the twin writes as the env's linear
    law; replayed on the run's reference it gives the diagnosis's own free-run error."""
    import sys

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import second_sim as S

    case = S.draw_case("control", 8, law="pid", saturate=False, log_every=1, effort=None)
    idx = case.index
    run = tmp_path / "run.csv"
    with open(run, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t", "x_ref", "x"])
        for row in zip(case.trace.t[idx], case.trace.x_ref[idx], case.trace.y_log[idx],
                       strict=True):
            w.writerow([repr(float(v)) for v in row])
    out = tmp_path / "pid.toml"
    assert diagnose_main([str(run), "--json", str(tmp_path / "d.json"), "--env-out", str(out),
                          "--env-id", "fricbench/PidTwin-v0", "--quiet"]) == EXIT_OK
    report = json.loads((tmp_path / "d.json").read_text())
    ctrl = tomllib.loads(out.read_text())["axis"]["controller"]
    assert ctrl["law"] == "linear" and len(ctrl["law_recursion"]) == 2
    sim = _replay(tmp_path, monkeypatch, "fricbench/PidTwin-v0", run)
    measured = case.trace.y_log[idx]
    rms = float(np.sqrt(np.mean((sim - measured) ** 2)))
    pos = report["position"]
    assert rms <= 1.2 * float(np.hypot(pos["rms_after"], case.floor)), (rms, pos)
    assert rms < 0.5 * pos["rms_before"], (rms, pos)


@pytest.mark.parametrize("v_heat", [0.0, 0.012])
def test_thermal_law_survives_into_the_twin(v_heat: float) -> None:
    """A diagnosed drift keeps its law: the heating speed (0: of time) is written and packed."""
    from fricbench.axis import Axis
    from fricbench.axis import plant as PL
    from fricbench.sysid.diagnose.twin import _axis_tables, _check_round_trip

    p = PL.default_row(10.0, 10.0)  # 400 kg and 400 N s/m at 40 N per effort unit
    p[PL.FC] = 3.0
    p[PL.TH_AMP], p[PL.TH_TAU], p[PL.TH_VHEAT] = -6e-6, 4.5, v_heat
    tables = _axis_tables(p, 40.0)
    effects = tables["effects"]
    assert effects["thermal_drift"] == -6e-6 and effects["thermal_time_constant"] == 4.5
    assert effects.get("thermal_heating_speed", 0.0) == v_heat
    axis = Axis.from_dict({k: tables[k] for k in ("mechanics", "friction", "effects")})
    _check_round_trip(axis, p, 40.0)
    packed = axis.pack()
    assert packed[PL.TH_VHEAT] == v_heat and packed[PL.TH_TAU] == 4.5


@pytest.mark.parametrize("knots", [(), (0.0, 0.35, -0.1)])
def test_a_friction_profile_survives_into_the_twin(knots: tuple[float, ...]) -> None:
    """A friction profile along the stroke is written as its knots, start and span, and packs
    back to the same plant columns; without one no profile line is written."""
    from fricbench.axis import Axis
    from fricbench.axis import plant as PL
    from fricbench.sysid.diagnose.twin import _axis_tables, _check_round_trip

    p = PL.default_row(10.0, 10.0)
    p[PL.FC] = 3.0
    p[PL.PD_NKNOTS], p[PL.PD_START], p[PL.PD_SPAN] = len(knots), -0.02, 0.3
    p[PL.PD_KNOT0:PL.PD_KNOT0 + len(knots)] = knots
    tables = _axis_tables(p, 40.0)
    effects = tables["effects"]
    if knots:
        assert effects["friction_profile"] == knots
        assert effects["friction_profile_start"] == -0.02
        assert effects["friction_profile_span"] == 0.3
    else:
        assert not any(k.startswith("friction_profile") for k in effects), effects
    axis = Axis.from_dict({k: tables[k] for k in ("mechanics", "friction", "effects")})
    _check_round_trip(axis, p, 40.0)


@pytest.mark.parametrize(("fundamental", "sines", "cosines"), [
    (0.05, (0.0, 0.0), (0.0, 0.0)), (0.05, (0.02, 0.0), (-0.01, 0.0)),
    (0.05, (0.0, 0.005), (0.0, 0.004)), (0.0, (0.01, 0.0), (0.0, 0.0))])
def test_cogging_harmonics_survive_into_the_twin(fundamental: float,
                                                  sines: tuple[float, float],
                                                  cosines: tuple[float, float]) -> None:
    """The ripple's harmonics are written as amplitudes and phases in newtons and pack back
    to the same plant columns, with their period (harmonics without a fundamental too);
    without them no line is written."""
    from fricbench.axis import Axis
    from fricbench.axis import plant as PL
    from fricbench.sysid.diagnose.twin import _axis_tables, _check_round_trip

    p = PL.default_row(10.0, 10.0)
    p[PL.COG_SIN], p[PL.COG_PERIOD] = fundamental, 4e-3
    p[PL.COG_H2_SIN], p[PL.COG_H3_SIN] = sines
    p[PL.COG_H2_COS], p[PL.COG_H3_COS] = cosines
    tables = _axis_tables(p, 40.0)
    effects = tables["effects"]
    if any(sines) or any(cosines):
        amps = effects["cogging_harmonics"]
        assert amps[-1] == pytest.approx(40.0 * np.hypot(sines[-1] or sines[0],
                                                         cosines[-1] or cosines[0]))
    else:
        assert "cogging_harmonics" not in effects and "cogging_harmonic_phases" not in effects
    axis = Axis.from_dict({k: tables[k] for k in ("mechanics", "friction", "effects")})
    _check_round_trip(axis, p, 40.0)
    if any(sines) or any(cosines):
        assert axis.pack()[PL.COG_PERIOD] == 4e-3  # the harmonics' period is written too
