"""Malformed inputs of ``fricbench diagnose`` (issue 14 items 6-9).

Each case is a small CSV made from a short simulated run: it gives a one-line ``error: ...`` and
a non-zero exit, or an honest report (exit 0, every number finite, the problem in ``warnings``);
never a traceback, and the input file is left exactly as it was.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import threading
import time
from collections.abc import Callable

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.sysid import io as run_io
from fricbench.sysid.diagnose.command import EXIT_BAD_INPUT, EXIT_OK, main
from fricbench.trajectories.base import Reference

HEADER = "t,x_ref,x,u"


@pytest.fixture(scope="module")
def base() -> np.ndarray:
    """Two seconds of a simulated run with friction and noise: columns t, x_ref, x, u."""
    ts = 1e-3
    t = np.arange(2000) * ts
    s = np.clip((t - 0.1) / 0.3, 0.0, 1.0)
    x = (0.006 * np.sin(2 * np.pi * 1.0 * t) + 0.001 * np.sin(2 * np.pi * 4.2 * t)) * (
        s**3 * (10.0 - 15.0 * s + 6.0 * s**2))
    axis = Axis().with_effects(noise_std=5e-8, quantization=2e-8)
    res = simulate(axis, Reference.from_positions(t, x), seed=3)
    return np.column_stack([res.t, res.x_ref, res.x, res.u])


def _text(a: np.ndarray, header: str = HEADER) -> str:
    rows = "\n".join(f"{r[0]:.12g},{r[1]:.12g},{r[2]:.12g},{r[3]:.9g}" for r in a)
    return header + "\n" + rows + "\n"


def _scaled(col: slice | int, factor: float) -> Callable[[np.ndarray], bytes]:
    def build(a: np.ndarray) -> bytes:
        a = a.copy()
        a[:, col] *= factor
        return _text(a).encode()
    return build


def _cell(row: int, col: int, value: str) -> Callable[[np.ndarray], bytes]:
    """Data row ``row`` (file line ``row + 2``) with field ``col`` replaced by ``value``."""
    def build(a: np.ndarray) -> bytes:
        lines = _text(a).split("\n")
        fields = lines[row + 1].split(",")
        fields[col] = value
        lines[row + 1] = ",".join(fields)
        return "\n".join(lines).encode()
    return build


def _line(row: int, text: str) -> Callable[[np.ndarray], bytes]:
    """Data row ``row`` (file line ``row + 2``) replaced by ``text``."""
    def build(a: np.ndarray) -> bytes:
        lines = _text(a).split("\n")
        lines[row + 1] = text
        return "\n".join(lines).encode()
    return build


def _edit(fn: Callable[[np.ndarray], None]) -> Callable[[np.ndarray], bytes]:
    def build(a: np.ndarray) -> bytes:
        a = a.copy()
        fn(a)
        return _text(a).encode()
    return build


def _set_col(col: int, value: float) -> Callable[[np.ndarray], None]:
    def fn(a: np.ndarray) -> None:
        a[:, col] = value
    return fn


def _near_reference(a: np.ndarray) -> None:
    a[:, 2] = a[:, 1] + 1e-15 * np.random.default_rng(0).standard_normal(a.shape[0])


def _valid(a: np.ndarray) -> bytes:
    return _text(a).encode()


def _bytes_at(row: int, blob: bytes) -> Callable[[np.ndarray], bytes]:
    """Data row ``row`` with ``blob`` put into its measured-position cell."""
    def build(a: np.ndarray) -> bytes:
        lines = _text(a).encode().split(b"\n")
        fields = lines[row + 1].split(b",")
        fields[2] = fields[2] + blob
        lines[row + 1] = b",".join(fields)
        return b"\n".join(lines)
    return build


# (id, file builder, extra arguments, exit status, regex the error message must match)
REFUSED = [
    # item 6: off the scale of a servo axis, refused before any fit (was a SystemError traceback)
    ("positions x1e300", _scaled(slice(1, 3), 1e300), [],
     r"line \d+, column 'x_ref': position -?[\d.]+e\+29\d is outside \+-1000 m"),
    ("positions x1e-300", _scaled(slice(1, 3), 1e-300), [],
     r"column 'x_ref' moves by [\d.]+e-30\d m, less than the 1e-08 m"),
    ("one cell 1e300", _cell(500, 2, "1e300"), [],
     r"line 502, column 'x': position 1e\+300 is outside \+-1000 m"),
    ("time x1e300", _scaled(0, 1e300), [],
     r"column 't': sample time 1e\+297 s .*outside \[1e-06, 0.1\] s"),
    ("time x1e-300", _scaled(0, 1e-300), [],
     r"column 't': sample time 1e-303 s .*outside \[1e-06, 0.1\] s"),
    ("time in milliseconds", _scaled(0, 1e3), [],
     r"column 't': sample time 1 s .*is the column in seconds\?"),
    # item 6: parse errors with line and column (were _csv.Error tracebacks)
    ("unterminated quote", _cell(9, 2, '"0.001'), [],
     r"line 11, column 'x': bad quoting .*must close on its line"),
    ("quoted cell over two lines", _cell(9, 1, '"0.001\n0.002"'), [],
     r"line 11, column 'x_ref': bad quoting"),
    ("200000-character cell", _cell(9, 2, "1" * 200_000), [],
     r"line 11, column 'x': the line is longer than MAX_LINE_BYTES = 100000 bytes"),
    ("200000-character quoted cell", _cell(9, 3, '"' + "2" * 200_000), [],
     r"line 11, column 'u': the line is longer than MAX_LINE_BYTES"),
    ("NUL byte on line 30", _bytes_at(28, b"\x00"), [], r"line 30, byte \d+: NUL bytes"),
    ("not UTF-8 on line 30", _bytes_at(28, b"\xff\xfe"), [], r"line 30, byte \d+: not UTF-8"),
    # kept as regression tests: clean before, still clean
    ("non-numeric cell", _cell(10, 2, "abc"), [], r"line 12, column 'x': 'abc' is not a number"),
    ("ragged row", _cell(3, 3, "1.0,5"), [],
     r"line 5 has 5 fields, the header has 4: field 5 \(beyond the header\) holds '5'"),
    ("short row", _line(3, "0.003,0,0"), [],
     r"line 5 has 3 fields, the header has 4: column 'u' and after are missing"),
    # item 7: the reference equal to the measurement (was a ZeroDivisionError traceback)
    ("--reference x", _valid, ["--reference", "x"],
     r"the reference 'x' and the measured position 'x' are equal at every sample"),
    ("x equals x_ref to rounding", _edit(_near_reference), [],
     r"the reference 'x_ref' and the measured position 'x' are equal at every sample"),
    # item 7: a degenerate effort the user named is refused (was exit 0 with NaN, or a traceback)
    ("effort x1e300, named", _scaled(3, 1e300), ["--effort", "u"],
     r"column 'u': effort -?[\d.]+e\+30\d at line \d+ is beyond \+-1e\+12.*--no-effort"),
    ("constant effort, named", _edit(_set_col(3, 2.5)), ["--effort", "u"],
     r"column 'u' is constant \(2.5\)"),
    # item 9: numeric options (were accepted, and changed the result)
    ("--decimate 0", _valid, ["--decimate", "0"], r"--decimate 0: expected an integer >= 1"),
    ("--decimate -5", _valid, ["--decimate", "-5"], r"--decimate -5: expected an integer >= 1"),
    ("--decimate 21", _valid, ["--decimate", "21"],
     r"--decimate 21: expected an integer from 1 to 20 .*of its 2000\)"),
    ("--filter-hz 0", _valid, ["--filter-hz", "0"],
     r"--filter-hz 0: expected a positive cut-off frequency"),
    ("--filter-hz -3", _valid, ["--filter-hz", "-3"],
     r"--filter-hz -3: expected a positive cut-off frequency"),
    ("--filter-hz nan", _valid, ["--filter-hz", "nan"],
     r"--filter-hz nan: expected a positive cut-off frequency"),
    ("--filter-hz 500", _valid, ["--filter-hz", "500"],
     r"--filter-hz 500: expected a cut-off below 500 Hz, the Nyquist frequency"),
    ("--max-effects -1", _valid, ["--max-effects", "-1"],
     r"--max-effects -1: expected an integer >= 0"),
]


def _sha(path: str) -> tuple[str, float]:
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest(), os.path.getmtime(path)


def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    try:
        code = main(args)
    except SystemExit as exc:  # argparse refusing an option value
        code = int(exc.code or 0)
    return code, capsys.readouterr().err


@pytest.mark.parametrize(("build", "extra", "message"), [c[1:] for c in REFUSED],
                         ids=[c[0] for c in REFUSED])
def test_malformed_input_is_refused_cleanly(base, tmp_path, capsys, build, extra, message):
    path = tmp_path / "run.csv"
    path.write_bytes(build(base))
    before = _sha(str(path))
    out = tmp_path / "out.json"
    code, err = _run([str(path), "--quiet", "--json", str(out), *extra], capsys)
    assert "Traceback" not in err
    assert code == EXIT_BAD_INPUT, err
    lines = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(lines) == 1, err
    assert re.search(message, lines[0]), lines[0]
    assert not out.exists()
    assert _sha(str(path)) == before  # the input is never modified


def _finite_json(path: str) -> dict:
    text = open(path).read()
    assert "null" not in text and "NaN" not in text and "Infinity" not in text
    return json.loads(text)


# item 7: a degenerate effort found by default is dropped, with a warning printed and reported
@pytest.mark.parametrize(("build", "warning"), [
    (_scaled(3, 1e300), r"the effort is not used: column 'u': effort .* is beyond \+-1e\+12"),
    (_edit(_set_col(3, 2.5)), r"the effort is not used: column 'u' is constant \(2.5\)"),
], ids=["effort x1e300", "constant effort"])
def test_degenerate_effort_is_dropped_with_a_warning(base, tmp_path, capsys, build, warning):
    path = tmp_path / "run.csv"
    path.write_bytes(build(base))
    before = _sha(str(path))
    out = tmp_path / "out.json"
    code, err = _run([str(path), "--quiet", "--max-effects", "0", "--json", str(out)], capsys)
    assert "Traceback" not in err
    assert code == EXIT_OK, err
    assert re.search(r"warning: " + warning, err), err
    data = _finite_json(str(out))
    assert data["data"]["mode"] == "position" and "effort" not in data
    assert "u" not in data["data"]["columns"]
    assert any(re.match(warning, w) for w in data["warnings"])
    assert _sha(str(path)) == before


# item 8: bounded reading
def test_oversized_file_is_refused_before_it_is_read(tmp_path, capsys):
    path = tmp_path / "huge.csv"
    with open(path, "wb") as fh:
        fh.truncate(2 * 2**30)  # a 2 GiB sparse file: refused from its size alone
    size, mtime = os.path.getsize(path), os.path.getmtime(path)
    t0 = time.perf_counter()
    code, err = _run([str(path), "--quiet"], capsys)
    assert time.perf_counter() - t0 < 2.0
    assert code == EXIT_BAD_INPUT and "Traceback" not in err
    assert f"{2 * 2**30} bytes, more than MAX_FILE_BYTES = {run_io.MAX_FILE_BYTES}" in err
    assert (os.path.getsize(path), os.path.getmtime(path)) == (size, mtime)


def test_too_many_rows_stops_reading_at_the_limit(base, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(run_io, "MAX_ROWS", 300)
    path = tmp_path / "run.csv"
    path.write_text(_text(base))
    code, err = _run([str(path), "--quiet"], capsys)
    assert code == EXIT_BAD_INPUT and "Traceback" not in err
    assert "line 302: more than MAX_ROWS = 300 data rows" in err


def _feed(path: str | int, payload: bytes, endless: bytes = b"") -> threading.Thread:
    """Write ``payload`` (then ``endless`` until the reader goes) into a FIFO or a pipe's
    write descriptor (closed at the end)."""
    def write() -> None:
        try:
            with open(path, "wb") as fh:
                fh.write(payload)
                for _ in range(10**6 if endless else 0):
                    fh.write(endless)
        except BrokenPipeError:
            pass

    thread = threading.Thread(target=write, daemon=True)
    thread.start()
    return thread


def _release(path: str) -> None:
    """Let a writer still blocked on opening the FIFO go on (to a broken pipe)."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    os.close(fd)


def test_fifo_with_a_valid_run_is_read_as_a_stream(base, tmp_path, capsys):
    fifo = str(tmp_path / "run.fifo")
    os.mkfifo(fifo)
    thread = _feed(fifo, _text(base).encode())
    out = tmp_path / "out.json"
    try:
        code, err = _run([fifo, "--quiet", "--max-effects", "0", "--json", str(out)], capsys)
    finally:
        thread.join(timeout=5.0)
        if thread.is_alive():
            _release(fifo)
    assert code == EXIT_OK and "Traceback" not in err, err
    assert _finite_json(str(out))["data"]["samples"] == base.shape[0]


def test_dev_stdin_with_a_valid_run_is_read_as_a_stream(base, tmp_path, capsys):
    r, w = os.pipe()
    saved = os.dup(0)
    os.dup2(r, 0)
    os.close(r)
    thread = _feed(w, _text(base).encode())
    out = tmp_path / "out.json"
    try:
        code, err = _run(["/dev/stdin", "--quiet", "--max-effects", "0", "--json", str(out)],
                         capsys)
    finally:
        os.dup2(saved, 0)
        os.close(saved)
        thread.join(timeout=5.0)
    assert code == EXIT_OK and "Traceback" not in err, err
    assert _finite_json(str(out))["data"]["samples"] == base.shape[0]


def test_endless_stream_with_a_bad_first_row_fails_at_once(tmp_path, capsys):
    fifo = str(tmp_path / "endless.fifo")
    os.mkfifo(fifo)
    thread = _feed(fifo, b"t,x_ref,x,u\n0.000,0,abc,0\n", endless=b"0.001,0,0,0\n" * 1000)
    t0 = time.perf_counter()
    try:
        code, err = _run([fifo, "--quiet"], capsys)
    finally:
        thread.join(timeout=5.0)
    assert time.perf_counter() - t0 < 5.0
    assert code == EXIT_BAD_INPUT and "line 2, column 'x': 'abc' is not a number" in err


def test_stream_longer_than_the_byte_limit_is_refused(base, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(run_io, "MAX_FILE_BYTES", 10_000)
    fifo = str(tmp_path / "run.fifo")
    os.mkfifo(fifo)
    thread = _feed(fifo, _text(base).encode())
    try:
        code, err = _run([fifo, "--quiet"], capsys)
    finally:
        thread.join(timeout=5.0)
    assert code == EXIT_BAD_INPUT
    assert "more than MAX_FILE_BYTES = 10000 bytes read" in err


# item 9 in the library: decim is checked, not silently mapped to 1
@pytest.mark.parametrize("decim", [0, -5, 2.5, True])
def test_diagnose_refuses_a_bad_decimation(base, decim):
    from fricbench.sysid.diagnose import diagnose
    from fricbench.sysid.io import validate_arrays

    run = validate_arrays(*base.T)
    with pytest.raises(ValueError, match=r"decim=.*expected an integer >= 1"):
        diagnose(run, decim=decim)


# item 7, whatever the cause: no exit 0 with a non-finite report, no traceback from arithmetic
class _InfiniteResult:
    def to_dict(self) -> dict[str, object]:
        return {"effects": [], "position": {"rms_before": float("inf"), "rms_after": 1e-6},
                "steps": [{"metrics": {"position_rms_m": float("nan")}}]}


@pytest.mark.parametrize(("fake", "message"), [
    (lambda *a, **k: _InfiniteResult(),
     r"error: the diagnosis gave non-finite results \(position\.rms_before = inf and 1 more\)"),
    (lambda *a, **k: 1 / 0, r"error: the diagnosis failed: division by zero"),
], ids=["non-finite report", "ZeroDivisionError"])
def test_a_failed_diagnosis_exits_one_and_writes_nothing(base, tmp_path, capsys, monkeypatch,
                                                         fake, message):
    from fricbench.sysid.diagnose import diagnosis

    monkeypatch.setattr(diagnosis, "diagnose", fake)
    path = tmp_path / "run.csv"
    path.write_text(_text(base))
    out = tmp_path / "out.json"
    code, err = _run([str(path), "--quiet", "--json", str(out)], capsys)
    assert code == 1 and "Traceback" not in err
    assert re.search(message, err), err
    assert not out.exists()
