"""The line printed when numba compiles the kernel: on a compilation only, once, kernel only."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numba
import pytest

import fricbench  # noqa: F401  (installs the listener)
from fricbench import _compile_notice
from fricbench._compile_notice import MESSAGE


def _fresh(module: str) -> Callable[[float], float]:
    """A function never compiled before, seemingly defined in ``module``."""
    def add_one(x: float) -> float:
        return x + 1.0

    add_one.__module__ = module
    return numba.njit(add_one)  # type: ignore[no-any-return]


def test_a_kernel_compilation_prints_one_line_once(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(_compile_notice._notice, "announced", False)
    first = _fresh("fricbench.axis.probe")
    assert first(1.0) == 2.0
    assert capsys.readouterr().err == MESSAGE + "\n"
    assert first(1) == 2.0  # another signature compiles again: said already
    assert _fresh("fricbench.gym.probe")(1.0) == 2.0
    assert capsys.readouterr().err == ""


def test_other_compilations_print_nothing(monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(_compile_notice._notice, "announced", False)
    assert _fresh("someone_else.module")(1.0) == 2.0
    assert _fresh("fricbench.compensators.probe")(1.0) == 2.0
    assert capsys.readouterr().err == ""


@pytest.mark.slow
def test_a_warm_cache_prints_nothing(tmp_path: Path) -> None:
    """Two processes on one cache folder: the first may compile (and says so when it does),
    the second loads the kernel from the cache and prints nothing."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path),
           "PYTHONPATH": os.pathsep.join([str(Path(fricbench.__file__).parents[1]),
                                          os.environ.get("PYTHONPATH", "")])}
    code = ("from fricbench.axis import simulate; from fricbench.gym import get_spec; "
            "from fricbench.trajectories import make_trajectory; "
            "axis = get_spec('fricbench/PaperAxis-v0').axis; "
            "simulate(axis, make_trajectory('s_curve', ts=axis.controller.ts))")
    runs = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                           text=True, check=True, timeout=600) for _ in range(2)]
    assert runs[0].stderr.count(MESSAGE) == 1  # an empty cache folder: it compiles
    assert MESSAGE not in runs[1].stderr
