"""A plant row driven open loop through the linear-law driver, for the plant's tests."""

from __future__ import annotations

import numpy as np

from fricbench.axis.linear_law import simulate_batch


def open_loop(row: np.ndarray, force: np.ndarray, ts: float, n_sub: int, v0: float = 0.0
              ) -> tuple[np.ndarray, np.ndarray]:
    """Logged (table) and motor positions of a plant row driven by ``force`` (no controller),
    from rest at 0 moving at ``v0``."""
    n = force.shape[0]
    other = np.empty((1, n))
    y, _, status = simulate_batch(row[None, :], np.zeros((1, 0)), np.zeros((1, 0)),
                                  force[None, :], np.arange(n) * ts, ts, n_sub=n_sub, x0=0.0,
                                  v0=v0, u_init=np.zeros((1, 0)), y_init=np.zeros(0),
                                  other=other)
    assert status[0] == 0
    return y[0], other[0]
