"""Loading and validating run files: every bad input gives a clear DataError."""

from __future__ import annotations

import hashlib
import os

import numpy as np
import pytest

from fricbench.sysid.io import MIN_SAMPLES, DataError, RunData, load_run, validate_arrays


def _write(path, header: str, rows: list[str]) -> str:
    text = header + "\n" + "\n".join(rows) + "\n"
    path.write_text(text)
    return str(path)


def _good_rows(n: int = 400, ts: float = 1e-3, scale: float = 1.0) -> list[str]:
    t = np.arange(n) * ts
    xr = scale * 0.01 * np.sin(2 * np.pi * 1.0 * t)
    x = xr - scale * 1e-6
    u = 10.0 * np.cos(2 * np.pi * t)
    return [f"{a:.9f},{b:.12g},{c:.12g},{d:.6g}" for a, b, c, d in zip(t, xr, x, u, strict=True)]


def test_good_file_loads_with_effort(tmp_path):
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", _good_rows())
    run = load_run(path)
    assert isinstance(run, RunData)
    assert run.n_samples == 400 and run.has_effort
    assert run.ts == pytest.approx(1e-3)
    assert run.n_reversals >= 1 and not run.warnings


def test_effort_is_optional_unless_named(tmp_path):
    rows = [",".join(r.split(",")[:3]) for r in _good_rows()]
    path = _write(tmp_path / "run.csv", "t,x_ref,x", rows)
    assert load_run(path).u is None
    with pytest.raises(DataError, match="missing column.*'force'.*has 't', 'x_ref', 'x'"):
        load_run(path, effort="force", effort_required=True)


def test_renamed_columns_semicolon_and_comments(tmp_path):
    rows = [r.replace(",", ";") for r in _good_rows()]
    path = _write(tmp_path / "run.csv", "# a comment\ntime;ref;pos;F", rows)
    run = load_run(path, time="time", reference="ref", position="pos", effort="F")
    assert run.has_effort and run.columns["x_ref"] == "ref"


def test_missing_column_lists_the_columns_found(tmp_path):
    path = _write(tmp_path / "run.csv", "t,q_ref,q,u", _good_rows())
    with pytest.raises(DataError) as err:
        load_run(path)
    msg = str(err.value)
    assert "'x_ref'" in msg and "'x'" in msg and "'q_ref'" in msg and "--reference" in msg


def test_non_numeric_cell_names_line_and_column(tmp_path):
    rows = _good_rows()
    fields = rows[10].split(",")
    fields[2] = "abc"
    rows[10] = ",".join(fields)
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", rows)
    with pytest.raises(DataError, match=r"line 12, column 'x': 'abc' is not a number"):
        load_run(path)


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_nan_and_inf_are_rejected(tmp_path, bad):
    rows = _good_rows()
    fields = rows[5].split(",")
    fields[1] = bad
    rows[5] = ",".join(fields)
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", rows)
    with pytest.raises(DataError, match=r"line 7, column 'x_ref'.*not finite"):
        load_run(path)


def test_time_not_increasing(tmp_path):
    rows = _good_rows()
    rows[20], rows[21] = rows[21], rows[20]
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", rows)
    with pytest.raises(DataError, match="does not increase"):
        load_run(path)


def test_irregular_sampling_beyond_one_percent(tmp_path):
    rows = _good_rows()
    del rows[100]  # one step of 2 ms in a 1 ms run
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", rows)
    with pytest.raises(DataError, match="irregular sampling"):
        load_run(path)


def test_jittered_timestamps_are_resampled_with_a_warning():
    # a PC logger: each timestamp off by up to +-10 % of the step, the motion a smooth sine
    n, ts = 2000, 1e-3
    rng = np.random.default_rng(1)
    t = np.arange(n) * ts + rng.uniform(-0.1 * ts, 0.1 * ts, n) * (np.arange(n) > 0)

    def motion(tt):
        return 0.01 * np.sin(2 * np.pi * 2.0 * tt)

    run = validate_arrays(t, motion(t), motion(t) - 1e-5, 5.0 * np.cos(2 * np.pi * 2.0 * t))
    assert run.ts == pytest.approx(ts, rel=0.02)
    assert np.allclose(np.diff(run.t), run.ts, rtol=1e-9, atol=0.0)
    # on the new grid the values are the motion's at the grid's times, closer than a linear
    # interpolation between the readings gets (off by the curvature)
    assert np.max(np.abs(run.x_ref - motion(run.t))) < 1e-3 * 0.01
    err = np.sqrt(np.mean((run.x - (motion(run.t) - 1e-5)) ** 2))
    linear = np.sqrt(np.mean((np.interp(run.t, t, motion(t)) - motion(run.t)) ** 2))
    assert err < 0.1 * linear
    # the effort, noisy in a real log, stays a linear interpolation of its readings
    assert np.allclose(run.u, np.interp(run.t, t, 5.0 * np.cos(2 * np.pi * 2.0 * t)),
                       rtol=0.0, atol=1e-12)
    warning = next(w for w in run.warnings if "resampled" in w)
    assert "jitter by up to" in warning and "%" in warning


def test_a_reference_latched_at_the_drives_ticks_is_read_at_them():
    # a drive's 2 kHz loop read by a PC every ~3 ms at jittered instants: the reference is the
    # one of the drive's last tick (up to 0.5 ms old), the position the sensor's at the stamp
    loop, n = 5e-4, 2000
    rng = np.random.default_rng(2)
    t = np.arange(n) * 6 * loop + rng.uniform(-0.6 * loop, 0.6 * loop, n) * (np.arange(n) > 0)

    def plan(tt):
        return 0.05 * np.sin(2 * np.pi * 0.7 * tt) + 0.02 * np.sin(2 * np.pi * 1.9 * tt)

    latched = plan(loop * np.floor(t / loop + 1e-9))
    run = validate_arrays(t, latched, plan(t) - 1e-5)
    # the reference on the grid is its readings at their ticks (linear between them), not the
    # readings interpolated at their stamps (off by the speed times up to 0.5 ms)
    ticks = loop * np.floor(t / loop + 1e-9)
    at_ticks = np.interp(run.t, ticks, latched)
    err = np.sqrt(np.mean((run.x_ref - at_ticks) ** 2))
    stamped = np.interp(run.t, t, latched)
    assert err < 0.1 * np.sqrt(np.mean((stamped - at_ticks) ** 2))
    # the position was read at its stamps and stays there (interpolated between them)
    err = run.x - (plan(run.t) - 1e-5)
    linear = np.interp(run.t, t, plan(t)) - plan(run.t)
    assert np.sqrt(np.mean(err**2)) < 0.2 * np.sqrt(np.mean(linear**2))
    warning = next(w for w in run.warnings if "resampled" in w)
    assert "loop ticks" in warning and "500 us" in warning and "position at its stamps" in warning


def test_a_resampled_rest_stays_at_rest():
    # stop-and-go moves read at jittered instants: between two readings of a rest the
    # resampled position neither moves nor overshoots the stop (a cubic spline rings there)
    n, ts = 3000, 2e-3
    rng = np.random.default_rng(3)
    t = np.arange(n) * ts + rng.uniform(-0.1 * ts, 0.1 * ts, n) * (np.arange(n) > 0)
    phase = np.clip((t % 1.0) / 0.4, 0.0, 1.0)  # a 0.4 s move, then 0.6 s at rest
    x = 0.01 * (np.floor(t / 1.0) + phase - np.sin(2 * np.pi * phase) / (2 * np.pi))
    run = validate_arrays(t, x, x - 1e-5, None, effort_required=False)
    lo, hi = np.min(x) - 1e-5, np.max(x) - 1e-5
    assert lo <= np.min(run.x) and np.max(run.x) <= hi
    for k in range(1, 5):
        rest = (run.t > k - 0.55) & (run.t < k - 0.05)  # well inside the k-th rest
        assert np.ptp(run.x[rest]) == 0.0


def test_small_jitter_is_accepted():
    n = 400
    t = np.arange(n) * 1e-3 + np.random.default_rng(0).uniform(-3e-8, 3e-8, n)
    xr = 0.01 * np.sin(2 * np.pi * t)
    run = validate_arrays(t, xr, xr - 1e-7)
    assert run.ts == pytest.approx(1e-3, rel=1e-4)


def test_too_short(tmp_path):
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", _good_rows(MIN_SAMPLES - 1))
    with pytest.raises(DataError, match="too short"):
        load_run(path)


def test_no_motion_says_no_analysis_is_possible():
    t = np.arange(500) * 1e-3
    with pytest.raises(DataError, match="without motion.*no analysis"):
        validate_arrays(t, np.zeros(500), np.zeros(500))


def test_no_reversal_is_a_warning_naming_the_skipped_analyses():
    t = np.arange(500) * 1e-3
    xr = 0.01 * t
    run = validate_arrays(t, xr, xr - 1e-7)
    assert run.n_reversals == 0
    assert any("never reverses" in w and "backlash" in w for w in run.warnings)


def test_a_reference_that_never_reverses_but_rests_shows_its_friction_at_the_starts():
    """Three moves of one direction, each from a rest: the friction level is judged on the
    starts (friction holds the axis at rest, a constant force would not); direction-
    dependent effects are still not tried."""
    t = np.arange(4000) * 1e-3
    ramp = np.clip((t % 1.0 - 0.3) / 0.5, 0.0, 1.0)
    xr = 0.01 * (np.floor(t) + ramp)
    run = validate_arrays(t, xr, xr - 1e-7)
    assert run.n_reversals == 0
    assert run.n_starts == 4
    text = " ".join(run.warnings)
    assert "judged on its 4 starts from rest" in text and "backlash are not tried" in text
    # one start is too little
    once = validate_arrays(t, 0.01 * np.clip((t - 0.3) / 3.0, 0.0, 1.0),
                           0.01 * np.clip((t - 0.3) / 3.0, 0.0, 1.0) - 1e-7)
    assert once.n_starts == 1
    assert any("coulomb_friction, stribeck_friction" in w and "not tried" in w
               for w in once.warnings)


def test_millimetres_are_suspected(tmp_path):
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", _good_rows(scale=1000.0))
    run = load_run(path)
    assert any("millimetres" in w for w in run.warnings)


@pytest.mark.parametrize(("unit", "per_si"), [("m", 1.0), ("mm", 1e3), ("deg", 180 / np.pi)])
def test_a_large_tracking_error_is_a_warning_in_the_users_unit(unit: str, per_si: float) -> None:
    """A measured position that is far from the reference (a wrong column, another unit, or
    a step response) is flagged with its rms in the unit the log was given in."""
    t = np.arange(2000) * 1e-3
    xr = np.where((t // 0.5) % 2 == 0, 0.0, 0.01)  # steps of 10 mm (or 10 mrad)
    xm = np.concatenate([[0.0], xr[:-1]]) * 0.5 + 0.0025 * np.sin(40 * t)  # far behind
    run = validate_arrays(t, xr, xm, position_unit=unit)  # SI in, labelled in `unit`
    err = float(np.sqrt(np.mean((xr - xm) ** 2))) * per_si
    hits = [w for w in run.warnings if "differs from the reference" in w]
    assert len(hits) == 1 and f"{err:.4g} {unit} rms" in hits[0]


def test_empty_file(tmp_path):
    path = tmp_path / "empty.csv"
    path.write_bytes(b"")
    with pytest.raises(DataError, match="empty"):
        load_run(str(path))


def test_header_only(tmp_path):
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", [])
    with pytest.raises(DataError, match="no data rows"):
        load_run(path)


def test_binary_file(tmp_path):
    path = tmp_path / "data.mat"
    path.write_bytes(b"MATLAB 5.0 MAT-file\x00\x01\x02\xff\xfe" * 50)
    with pytest.raises(DataError, match="binary"):
        load_run(str(path))


def test_missing_file(tmp_path):
    with pytest.raises(DataError, match="no such file"):
        load_run(str(tmp_path / "nope.csv"))


def test_ragged_row(tmp_path):
    rows = _good_rows()
    rows[3] = rows[3] + ",5"
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", rows)
    with pytest.raises(DataError, match="line 5 has 5 fields, the header has 4"):
        load_run(path)


def test_the_input_file_is_never_modified(tmp_path):
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", _good_rows())
    before = hashlib.sha256(open(path, "rb").read()).hexdigest()
    mtime = os.path.getmtime(path)
    load_run(path)
    assert hashlib.sha256(open(path, "rb").read()).hexdigest() == before
    assert os.path.getmtime(path) == mtime


def test_emps_files_load_with_their_names():
    root = os.path.join(os.environ["FRICBENCH_SHARED"], "data", "emps")
    if not os.path.isdir(root):
        pytest.fail(f"{root} is missing: the EMPS data are part of the shared data set")
    run = load_run(os.path.join(root, "emps_train.csv"), time="t_s", reference="q_ref_m",
                   position="q_m", effort="force_N", effort_required=True)
    assert run.n_samples == 24841 and run.n_reversals == 7 and not run.warnings
    assert run.ts == pytest.approx(1e-3, rel=1e-4)


def _effort_run(u: np.ndarray, **kwargs):
    t = np.arange(400) * 1e-3
    xr = 0.01 * np.sin(2 * np.pi * t)
    return validate_arrays(t, xr, xr - 1e-6, u, **kwargs)


@pytest.mark.parametrize(("u", "problem"), [
    (np.full(400, 2.5), "is constant"),
    (np.linspace(-1.0, 1.0, 400) * 1e300, "is beyond"),
    (np.linspace(-1.0, 1.0, 400) * 1e-300, "never exceeds"),
])
def test_degenerate_effort_raises_when_required_else_is_dropped(u, problem):
    with pytest.raises(DataError, match=problem):
        _effort_run(u)
    run = _effort_run(u, effort_required=False)
    assert run.u is None and "u" not in run.columns
    assert any(w.startswith("the effort is not used") and problem in w for w in run.warnings)


@pytest.mark.parametrize(("scale", "message"), [
    (1e6, r"position .* is outside \+-1000 m"),
    (1e-7, r"moves by .* less than the 1e-08 m"),
])
def test_positions_off_the_scale_of_an_axis(tmp_path, scale, message):
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", _good_rows(scale=scale))
    with pytest.raises(DataError, match=message):
        load_run(path)


def test_sample_time_off_the_scale_of_an_axis():
    t = np.arange(400) * 1.0
    xr = 0.01 * np.sin(2 * np.pi * t / 100)
    with pytest.raises(DataError, match=r"sample time 1 s .* outside \[1e-06, 0.1\] s"):
        validate_arrays(t, xr, xr - 1e-6)


# -- logs as they come: units, no time column, columns by index, separators -------------------
def _log_rows(n: int = 400, amplitude: float = 90.0, sep: str = ",") -> list[str]:
    """A log without a time column: reference, measurement, effort (positions in deg)."""
    k = np.arange(n)
    xr = amplitude * np.sin(2 * np.pi * k / 200)
    x = xr - 0.5
    u = 100.0 * np.cos(2 * np.pi * k / 200)
    return [sep.join(f"{v:.6g}" for v in row) for row in zip(xr, x, u, strict=True)]


def test_position_unit_converts_to_si_and_degrees_are_not_millimetres(tmp_path):
    path = _write(tmp_path / "run.csv", "t,x_ref,x,u", _good_rows(scale=1000.0))
    run = load_run(path, position_unit="mm")
    np.testing.assert_allclose(run.x_ref, 1e-3 * load_run(path).x_ref, rtol=1e-12)
    assert not any("millimetres" in w for w in run.warnings)
    assert run.units["position"] == "m" and run.units["position_logged"] == "mm"
    deg = _write(tmp_path / "deg.csv", "Channel 1,Channel 2,Channel 3",
                 _log_rows(amplitude=90.0))
    run = load_run(deg, time=None, reference="Channel 1", position="Channel 2",
                   effort="Channel 3", sample_time=2e-3, position_unit="deg")
    np.testing.assert_allclose(np.max(run.x_ref), np.pi / 2, rtol=1e-6)
    assert run.units["position"] == "rad" and run.units["position_logged"] == "deg"
    assert not any("millimetres" in w for w in run.warnings)
    with pytest.raises(ValueError, match="position unit 'inch'"):
        load_run(deg, sample_time=2e-3, position_unit="inch")


def test_scale_checks_apply_after_conversion(tmp_path):
    # 2000 mm = 2 m: within +-1000 m once converted, refused when read as metres
    rows = [f"{i * 1e-3:.3f},{2000 * np.sin(i / 50):.6g},{2000 * np.sin(i / 50) - 1:.6g}"
            for i in range(400)]
    path = _write(tmp_path / "run.csv", "t,x_ref,x", rows)
    with pytest.raises(DataError, match=r"outside \+-1000 m"):
        load_run(path)
    assert np.max(np.abs(load_run(path, position_unit="mm").x_ref)) < 2.0
    # 2e6 deg = 34907 rad: off the scale in rad as well
    rows = [f"{i * 1e-3:.3f},{2e6 * np.sin(i / 50):.6g},{2e6 * np.sin(i / 50) - 1:.6g}"
            for i in range(400)]
    path = _write(tmp_path / "big.csv", "t,x_ref,x", rows)
    with pytest.raises(DataError, match=r"outside \+-1000 rad \(after conversion from deg\)"):
        load_run(path, position_unit="deg")


def test_sample_time_builds_the_time_axis(tmp_path):
    path = _write(tmp_path / "run.csv", "r,y,u", _log_rows())
    run = load_run(path, reference="r", position="y", effort="u", sample_time=2e-3)
    np.testing.assert_allclose(run.t[:3], [0.0, 2e-3, 4e-3])
    assert run.ts == pytest.approx(2e-3) and run.n_samples == 400
    with pytest.raises(DataError, match="missing column.*'t'.*give the sample time.*--sample-time"):
        load_run(path, reference="r", position="y")
    with pytest.raises(DataError, match="no time column and no sample time"):
        load_run(path, time=None, reference="r", position="y")
    timed = _write(tmp_path / "timed.csv", "t,x_ref,x,u", _good_rows())
    with pytest.raises(DataError, match="has a time column 't' and a sample time"):
        load_run(timed, sample_time=1e-3)


def test_columns_by_zero_based_index(tmp_path):
    path = _write(tmp_path / "run.csv", "Channel 1,Channel 2,Channel 3", _log_rows())
    by_index = load_run(path, time=None, reference=0, position="1", effort=2,
                        sample_time=1e-3)
    by_name = load_run(path, time=None, reference="Channel 1", position="Channel 2",
                       effort="Channel 3", sample_time=1e-3)
    np.testing.assert_array_equal(by_index.x, by_name.x)
    assert by_index.columns["x"] == "Channel 2" and by_index.u is not None
    with pytest.raises(DataError, match="missing column.*'7'.*0-based index"):
        load_run(path, time=None, reference=0, position="7", sample_time=1e-3)
    # a header name wins over an index
    named = _write(tmp_path / "named.csv", "1,0,u", _log_rows())
    run = load_run(named, time=None, reference="0", position="1", sample_time=1e-3)
    np.testing.assert_allclose(run.x_ref[:3], by_name.x[:3])


def test_semicolons_and_a_decimal_comma(tmp_path):
    rows = _log_rows(sep=";")
    path = _write(tmp_path / "halscope.csv", "ref;pos;u", rows)
    assert load_run(path, reference="ref", position="pos", sample_time=1e-3).n_samples == 400
    comma = _write(tmp_path / "comma.csv", "ref;pos;u", [r.replace(".", ",") for r in rows])
    with pytest.raises(DataError,
                       match=r"line 2, column 'pos': '-0,5' has a decimal comma.*decimal point"):
        load_run(comma, reference="ref", position="pos", sample_time=1e-3)
