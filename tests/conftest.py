"""Shared fixtures."""

from __future__ import annotations

import os

# first, before matplotlib loads numpy: the CPU dispatch pins of fricbench.reproducible
import fricbench  # noqa: F401  # isort: skip

import matplotlib

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")
