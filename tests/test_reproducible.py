"""fricbench.reproducible: the CPU dispatch pins take effect when fricbench loads before numpy."""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys

import pytest

from fricbench import reproducible as R

X86 = platform.machine().lower() in ("x86_64", "amd64")

_PROBE = """
import json, os, sys
{pre}
import fricbench
import numpy
from numpy._core._multiarray_umath import __cpu_features__ as feats
from fricbench.reproducible import pin_cpu_dispatch
import fricbench.reproducible as R
print(json.dumps({{"env": {{k: os.environ.get(k) for k in ("NPY_DISABLE_CPU_FEATURES",
                                                        *R.AVX2_PINS)}},
                  "v4": feats.get("X86_V4", False), "avx512f": feats.get("AVX512F", False),
                  "again": pin_cpu_dispatch()}}))
"""


def _probe(pre: str = "", **env: str) -> dict:
    clean = {k: v for k, v in os.environ.items()
             if k not in ("NPY_DISABLE_CPU_FEATURES", *R.AVX2_PINS)}
    clean.update(env)
    out = subprocess.run([sys.executable, "-c", _PROBE.format(pre=pre)], env=clean,
                         capture_output=True, text=True, check=True, timeout=300)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not X86, reason="the pins are for x86-64 CPUs")
def test_importing_fricbench_first_pins_numpy_below_avx512_and_the_blas_to_avx2():
    got = _probe()
    assert got["env"]["NPY_DISABLE_CPU_FEATURES"] in R.NUMPY_FEATURES_OFF.values()
    # numpy >= 2.4 reports the x86-64-v4 group; earlier numpy the AVX512F target
    assert not got["v4"]
    flags = R._cpu_flags()
    for key, value in R.AVX2_PINS.items():
        assert got["env"][key] == (value if {"avx2", "fma"} <= flags else None)
    # numpy is loaded by then: a second call cannot change anything and says so
    assert got["again"] is False


@pytest.mark.skipif(not X86, reason="the pins are for x86-64 CPUs")
def test_a_users_own_setting_is_kept():
    mine = {"NPY_DISABLE_CPU_FEATURES": "", "OPENBLAS_CORETYPE": "Prescott",
            "ATEN_CPU_CAPABILITY": "default", "MKL_CBWR": "COMPATIBLE",
            "ONEDNN_MAX_CPU_ISA": "SSE41"}
    assert set(mine) == {"NPY_DISABLE_CPU_FEATURES", *R.AVX2_PINS}
    got = _probe(**mine)
    assert got["env"] == mine


def test_numpy_loaded_before_fricbench_is_left_as_it_is():
    got = _probe(pre="import numpy")
    assert set(got["env"].values()) == {None}


def test_this_test_session_runs_pinned():
    # tests/conftest.py imports fricbench before matplotlib (which loads numpy)
    if X86:
        assert os.environ.get("NPY_DISABLE_CPU_FEATURES") is not None
