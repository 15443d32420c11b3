"""Shared fixtures."""

from __future__ import annotations

import os

# first, before matplotlib loads numpy: the CPU dispatch pins of fricbench.reproducible
import fricbench  # noqa: F401  # isort: skip

import matplotlib

matplotlib.use("Agg")

# The shared data set (EMPS, the DC-motor logs) lies beside the checkout (``../shared``, as on
# CI's fresh clone); /work/shared is the development machines' copy. Tests read the directory
# from FRICBENCH_SHARED, which a caller may also set.
_BESIDE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "..", "shared")
os.environ.setdefault(
    "FRICBENCH_SHARED",
    os.path.normpath(_BESIDE) if os.path.isdir(os.path.join(_BESIDE, "data")) else "/work/shared")
os.environ.setdefault("MPLBACKEND", "Agg")
