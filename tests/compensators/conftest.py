"""Shared fixtures of the compensator tests."""

from __future__ import annotations

from typing import Any

import pytest

# lighter settings so the sweeps over the registry stay quick; the defaults are exercised in
# the module tests
LIGHT: dict[str, dict[str, Any]] = {
    "friction-ff": {"n_runs": 1, "run_duration": 8.0, "v_eps_grid": (1e-4,),
                    "advance_grid": (1,)},
    "ilc": {"iterations": 3},
    "tf-precomp": {"n_runs": 1, "run_duration": 8.0},
    "greybox-precomp": {"n_runs": 1, "run_duration": 8.0},
    "tf-lstm-precomp": {"n_runs": 1, "run_duration": 8.0,
                        "predictor_kwargs": {"max_epochs": 1, "hidden_size": 4}},
}


@pytest.fixture(scope="session")
def light() -> dict[str, dict[str, Any]]:
    """Constructor keywords per compensator id that keep its fit short."""
    return LIGHT
