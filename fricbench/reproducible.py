"""Same numbers on every x86-64 machine: numpy's, OpenBLAS's and torch's CPU dispatch pinned.

numpy picks the SIMD kernels of ``exp``, ``log``, ``power``, ``expm1``, ``log1p``,
``arctan``, ``arctan2``, ``tan``, ``sinh``, ``cbrt`` ... by the CPU it loads on, and its
AVX-512 kernels round differently from the AVX2 and scalar ones (last-bit differences). A
benchmark amplifies them: a stick-slip event one sample earlier moves a run's peak error, and
the leaderboards written on an AVX2 machine were not reproduced on an AVX-512 one (PaperAxis-v0
seed 0, no compensation, curve: 18.956 um there, 18.886 um here), while the same code with
numpy's AVX-512 kernels disabled reproduced them bit for bit. OpenBLAS does the same for its
BLAS and LAPACK kernels (SkylakeX against Haswell), which the least-squares fits call, and so
do torch's kernels (ATen) and its BLAS (MKL), which the LSTM and the policies run on.

Both libraries read their setting once, when they load, so :func:`pin_cpu_dispatch` must run
before numpy is imported: ``import fricbench`` does it first (the CLI always), and the tests'
``conftest.py`` imports fricbench before anything else. It imports only the standard library.
A setting the user made (``NPY_DISABLE_CPU_FEATURES``, ``OPENBLAS_CORETYPE``,
``ATEN_CPU_CAPABILITY``, ``MKL_CBWR``, ``ONEDNN_MAX_CPU_ISA``) is kept, and an empty
``NPY_DISABLE_CPU_FEATURES`` lets numpy use every kernel of the CPU. numba compiles for the host
CPU; pinning its target (``NUMBA_CPU_NAME=haswell``) changed none of the benchmark's figures.

Measured on an AVX-512 machine (AMD EPYC): with these pins ``make bench`` reproduced every row
of the six committed tables, written on an AVX2 machine, bit for bit, except those of
``tf-lstm-precomp`` (its LSTM runs on oneDNN, and which kernels the AVX2 machine ran is not
known); without them every table differed, and with numpy's pin alone 658 rows still moved (the
fits on OpenBLAS, the policies on torch). The pins cost no time there (the 40,000-sample
diagnosis timing: 13.1 and 13.6 s pinned, 13.5 and 13.7 s unpinned, run alternately).
"""

from __future__ import annotations

import os
import platform
import sys
from importlib import metadata

__all__ = ["pin_cpu_dispatch", "NUMPY_FEATURES_OFF", "AVX2_PINS"]

NUMPY_FEATURES_OFF = {
    # numpy >= 2.4 groups the AVX-512 targets as x86-64-v4 and two newer levels
    "new": "X86_V4 AVX512_ICL AVX512_SPR",
    # earlier numpy names each AVX-512 target
    "old": "AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL "
           "AVX512_ICL AVX512_SPR",
}
"""numpy dispatch targets switched off (``NPY_DISABLE_CPU_FEATURES``): the AVX-512 ones, so
that an AVX-512 machine runs the kernels an AVX2 machine runs."""

AVX2_PINS = {
    # OpenBLAS's kernel set that AVX2 machines (Intel since Haswell, AMD Zen) run
    "OPENBLAS_CORETYPE": "Haswell",
    # torch's own kernels (ATen), its BLAS (MKL) and oneDNN (its LSTM): their AVX2 code paths
    "ATEN_CPU_CAPABILITY": "avx2", "MKL_CBWR": "AVX2", "ONEDNN_MAX_CPU_ISA": "AVX2"}
"""The variables set on a CPU with AVX2 and FMA (each kept when the user set it)."""


def _numpy_names() -> str:
    try:
        major, minor = (int(p) for p in metadata.version("numpy").split(".")[:2])
    except (metadata.PackageNotFoundError, ValueError):
        return NUMPY_FEATURES_OFF["new"]
    return NUMPY_FEATURES_OFF["new" if (major, minor) >= (2, 4) else "old"]


def _cpu_flags() -> set[str]:
    """The CPU's feature flags (Linux), empty when unknown."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as fh:
            for line in fh:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def pin_cpu_dispatch() -> bool:
    """Pin numpy's SIMD dispatch below AVX-512, OpenBLAS's and torch's kernels to AVX2 (x86-64).

    Returns
    -------
    bool
        True when numpy was not loaded yet (the pins take effect, or the user's own settings
        stand); False when numpy was already imported (nothing can be changed any more: the
        numbers are this CPU's).
    """
    if "numpy" in sys.modules:
        return False
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return True
    os.environ.setdefault("NPY_DISABLE_CPU_FEATURES", _numpy_names())
    flags = _cpu_flags()
    # an AVX2 kernel on a CPU without AVX2 would stop on an illegal instruction
    if {"avx2", "fma"} <= flags:
        for key, value in AVX2_PINS.items():
            os.environ.setdefault(key, value)
    return True

