"""``fricbench diagnose`` on the command line: exit codes, messages, JSON keys, atomic report."""

from __future__ import annotations

import hashlib
import json
import math
import os
import re

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.sysid.diagnose.command import EXIT_BAD_INPUT, EXIT_OK, main
from fricbench.trajectories.base import Reference


def _reference(duration: float = 5.0, ts: float = 1e-3) -> Reference:
    t = np.arange(int(duration / ts)) * ts
    s = np.clip((t - 0.2) / 0.5, 0.0, 1.0)
    x = (0.006 * np.sin(2 * np.pi * 0.5 * t) + 0.001 * np.sin(2 * np.pi * 2.1 * t)) * (
        s**3 * (10.0 - 15.0 * s + 6.0 * s**2))
    return Reference.from_positions(t, x)


@pytest.fixture(scope="module")
def run_csv(tmp_path_factory) -> str:
    """A simulated run with friction, noise and the effort, in the default column names."""
    axis = Axis().with_effects(noise_std=5e-8, quantization=2e-8)
    res = simulate(axis, _reference(), seed=3)
    path = tmp_path_factory.mktemp("runs") / "run.csv"
    rows = "\n".join(f"{a:.6f},{b:.12g},{c:.12g},{d:.9g}"
                     for a, b, c, d in zip(res.t, res.x_ref, res.x, res.u, strict=True))
    path.write_text("t,x_ref,x,u\n" + rows + "\n")
    return str(path)


def _sha(path: str) -> str:
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def test_json_keys_and_atomic_report(run_csv, tmp_path, capsys):
    before = _sha(run_csv)
    out = tmp_path / "out.json"
    report_dir = tmp_path / "report"
    code = main([run_csv, "--json", str(out), "--report", str(report_dir), "--quiet"])
    assert code == EXIT_OK
    data = json.loads(out.read_text())
    assert {"effects", "position", "effort", "steps"} <= set(data)
    assert set(data["position"]) == {"rms_before", "rms_after", "max_before", "max_after"}
    assert set(data["effort"]) >= {"relerr_before_pct", "relerr_after_pct",
                                    "relerr_sliding_before_pct", "relerr_sliding_after_pct"}
    assert all(math.isfinite(v) and v >= 0.0 for v in data["effort"].values())
    assert "coulomb_friction" in data["effects"]
    assert data["position"]["rms_after"] < data["position"]["rms_before"]
    for step in data["steps"]:
        assert {"effect", "parameters", "metrics"} <= set(step)
    names = sorted(os.listdir(report_dir))
    assert "report.json" in names and "residual_reversals.png" in names
    assert not [n for n in names if n.endswith(".tmp")]  # no leftovers of atomic writes
    assert _sha(run_csv) == before  # the input is never modified
    printed = capsys.readouterr().out
    assert "effects found" in printed and "elapsed" in printed
    # the values printed under "effects found" are the final model's, the JSON's and the
    # twin's (each step's are those it was added with, before the later refits)
    assert set(data["parameters"]) == set(data["effects"])
    final = data["steps"][-1]["model"] if data["steps"] else None
    # each with its standard deviation from the final model's Jacobian (parameter_sd)
    assert set(data["parameter_sd"]) == set(data["effects"])
    for name, values in data["parameters"].items():
        sd = data["parameter_sd"][name]
        assert set(sd) == set(values)
        assert all(math.isfinite(v) and v >= 0.0 for v in sd.values())
        line = f"  {name}: " + ", ".join(f"{k}={v:.4g} +- {sd[k]:.2g}" for k, v in values.items())
        assert line in printed.splitlines(), (line, printed)
    assert final is None or set(final["effects"]) == set(data["effects"])


def test_validation_and_position_only(run_csv, tmp_path):
    out = tmp_path / "out.json"
    code = main([run_csv, "--validate", run_csv, "--no-effort", "--json", str(out), "--quiet",
                 "--max-effects", "1"])
    assert code == EXIT_OK
    data = json.loads(out.read_text())
    assert "effort" not in data and len(data["effects"]) <= 1
    assert set(data["validation"]["position"]) == {"rms_before", "rms_after", "max_before",
                                                   "max_after"}


@pytest.mark.parametrize(("content", "message"), [
    (b"", "empty"),
    (b"\x00\x01\x02binary\xff", "binary"),
    (b"t,q,r\n0,1,2\n", "missing column"),
    (b"t,x_ref,x\n" + b"".join(f"{i * 1e-3},{i},{i}\n".encode() for i in range(50)),
     "too short"),
])
def test_bad_input_exits_two_without_traceback(tmp_path, capsys, content, message):
    path = tmp_path / "bad.csv"
    path.write_bytes(content)
    code = main([str(path), "--quiet"])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT
    assert message in err and "Traceback" not in err


def test_named_effort_column_must_exist(run_csv, capsys):
    code = main([run_csv, "--effort", "current_A", "--quiet"])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT and "'current_A'" in err and "'u'" in err


def test_missing_output_directory(run_csv, tmp_path, capsys):
    code = main([run_csv, "--json", str(tmp_path / "nope" / "out.json"), "--quiet"])
    assert code == EXIT_BAD_INPUT and "does not exist" in capsys.readouterr().err


@pytest.fixture(scope="module")
def rotary_log(tmp_path_factory) -> str:
    """A short simulated run written as a rotary log: no time column, degrees, by index."""
    res = simulate(Axis(), _reference(duration=1.0), seed=1)
    deg = 180.0 / np.pi * 100.0  # the 6 mm stroke read as 0.6 rad
    path = tmp_path_factory.mktemp("rot") / "log.csv"
    rows = "\n".join(f"{a * deg:.9g};{b * deg:.9g};{c:.9g}"
                     for a, b, c in zip(res.x_ref, res.x, res.u, strict=True))
    path.write_text("Channel 1;Channel 2;Channel 3\n" + rows + "\n")
    return str(path)


def test_rotary_log_without_time_column(rotary_log, tmp_path, capsys):
    out = tmp_path / "out.json"
    code = main([rotary_log, "--sample-time", "0.001", "--position-unit", "deg",
                 "--reference", "0", "--position", "1", "--effort", "Channel 3",
                 "--max-effects", "0", "--json", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert code == EXIT_OK, captured.err
    assert "millimetres" not in captured.err
    assert " deg" in captured.out and not re.search(r"\b(um|mm/s)\b", captured.out)
    data = json.loads(out.read_text())
    assert data["data"]["position_unit"] == "deg" and data["data"]["position_unit_si"] == "rad"
    assert "position_rms_rad" in data["linear_model"]
    assert "prediction_floor_rad" in data["noise_floor"]
    assert not any(k.endswith("_m") for k in data["noise_floor"])


def test_progress_lines_give_the_log_unit(rotary_log, capsys):
    code = main([rotary_log, "--sample-time", "0.001", "--position-unit", "deg",
                 "--reference", "0", "--position", "1", "--effort", "Channel 3",
                 "--max-effects", "0"])
    err = capsys.readouterr().err
    assert code == EXIT_OK, err
    line = next(ln for ln in err.splitlines() if "linear position rms" in ln)
    assert re.search(r"linear position rms [0-9.e+-]+ deg ", line), line
    assert not re.search(r"rms [0-9.e+-]+ (rad|m)\b", err), err


@pytest.mark.parametrize(("extra", "message"), [
    (["--sample-time", "0.001", "--time", "t"], "give one"),
    (["--sample-time", "-1"], "positive time step"),
    ([], "--sample-time"),
])
def test_time_axis_options(rotary_log, capsys, extra, message):
    code = main([rotary_log, "--reference", "0", "--position", "1", "--quiet", *extra])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT and message in err and "Traceback" not in err


def test_an_effort_without_a_stated_unit_is_labelled_n_with_a_warning(run_csv, tmp_path,
                                                                       capsys):
    out = tmp_path / "out.json"
    assert main([run_csv, "--json", str(out), "--quiet"]) == EXIT_OK
    data = json.loads(out.read_text())
    said = [w for w in data["warnings"] if "--effort-unit" in w]
    assert len(said) == 1 and "labelled N" in said[0]
    assert "--effort-unit" in capsys.readouterr().err
    assert any(k.endswith("_N") for step in data["steps"] for k in step["parameters"])
    # stated, the unit labels the forces and nothing is assumed
    out_a = tmp_path / "out_a.json"
    assert main([run_csv, "--json", str(out_a), "--quiet", "--effort-unit", "A"]) == EXIT_OK
    data_a = json.loads(out_a.read_text())
    assert not [w for w in data_a["warnings"] if "--effort-unit" in w]
    keys = [k for step in data_a["steps"] for k in step["parameters"]]
    assert any(k.endswith("_A") for k in keys) and not any(k.endswith("_N") for k in keys)


@pytest.mark.parametrize(("extra", "message"), [
    (["--try", "friction_profile_4"], "--try 'friction_profile_4': expected an effect of the "
                                      "library"),
    (["--try", "friction_profile_5", "--open-loop"], "--try: the open-loop search tries its "
                                                     "own library"),
])
def test_try_names_an_effect_of_the_library(run_csv, capsys, extra, message):
    code = main([run_csv, "--quiet", *extra])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT and message in err and "Traceback" not in err


def test_try_adds_an_effect_the_search_leaves_out(run_csv, capsys):
    """``--try`` puts an effect tried only when asked among the candidates: the profile is
    scored at the steps where Coulomb friction is in (the progress lines name it); without
    ``--try`` it is never scored."""
    assert main([run_csv, "--max-effects", "2"]) == EXIT_OK
    assert "friction_profile_5" not in capsys.readouterr().err
    assert main([run_csv, "--max-effects", "2", "--try", "friction_profile_5"]) == EXIT_OK
    assert "friction_profile_5" in capsys.readouterr().err
