"""``none``: the plain cascade, no compensation (the reference row of every leaderboard)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from fricbench.compensators.base import Compensator

__all__ = ["NoCompensation"]


class NoCompensation(Compensator):
    """Always acts 0: what the axis does on its own."""

    id = "none"
    # uses nothing beforehand; leaderboards show it as the reference row of every category
    category: ClassVar[str] = "online"

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return np.zeros(self.context.n_axes)

    def _planned(self, n_steps: int) -> np.ndarray:
        return np.zeros((self.context.n_axes, n_steps))
