"""The solver benchmark compares like with like: same problems, costs from both solvers."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.bench.solver_benchmark import (
    _own_foh,
    compare_fits,
    compare_regressions,
)
from fricbench.sysid import tf_fit


def test_former_hold_matches_the_library_hold():
    num, den = np.array([1.0, 30.0, 500.0]), np.array([1.0, 60.0, 2500.0, 40000.0])
    b_own, a_own = _own_foh(num, den, 1e-3)
    b_lib, a_lib = tf_fit._foh(num, den, 1e-3)
    assert b_lib == pytest.approx(b_own, rel=1e-9, abs=1e-12)
    assert a_lib == pytest.approx(a_own, rel=1e-9, abs=1e-12)


def test_regressions_the_former_active_set_gets_wrong_count_against_it():
    rng = np.random.default_rng(3)
    X = rng.standard_normal((400, 3))
    X[:, 2] = -X[:, 1] + 0.3 * rng.standard_normal(400)
    y = X @ np.array([1.0, -1.0, -0.1]) + 0.01 * rng.standard_normal(400)
    cmp = compare_regressions([((X, y, np.array([False, True, True])), {})], "toy", repeat=1)
    assert cmp.n_problems == 1 and cmp.lib_better == 1 and cmp.lib_cost < cmp.own_cost
    assert "time library/own" in "\n".join(cmp.lines())


def test_fit_comparison_on_a_bounded_problem():
    target = np.array([0.3, -2.0])

    def residuals(thetas: np.ndarray) -> np.ndarray:
        return np.array([np.r_[th - target, 0.1 * th[0] * th[1]] for th in thetas])

    args = (residuals, np.array([1.0, 1.0]), np.array([0.0, -1.0]), np.array([2.0, 2.0]),
            np.array([1e-6, 1e-6]))
    cmp = compare_fits([(args, {"max_iter": 50})], "toy")
    assert cmp.lib_cost == pytest.approx(cmp.own_cost, rel=1e-3)
