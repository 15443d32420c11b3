"""The bench scores an env on its own trajectories, with the parameters its spec gives them."""

from __future__ import annotations

import numpy as np

from fricbench.bench.runner import _env_trajectory, bench_env
from fricbench.compensators import make_compensator


def test_a_spec_parameterised_trajectory_keeps_its_parameters() -> None:
    choice = _env_trajectory("fricbench/EMPS-v0", "s_curve")
    assert choice.id == "s_curve" and choice.params["distance"] == 0.197
    env = bench_env("fricbench/EMPS-v0", make_compensator("none"), seed=0)
    env.reset(seed=0, options={"trajectory": choice})
    assert env.reference is not None
    assert abs(np.max(env.reference.x) - 0.197) < 1e-9


def test_a_bare_id_stays_a_bare_id() -> None:
    assert _env_trajectory("fricbench/PaperAxis-v0", "circle") == "circle"
    choice = _env_trajectory("fricbench/PaperAxis-v0", "m_serial")
    assert choice.id == "m_serial" and not choice.params
