"""What a learning compensator may use in ``fit``: the env's axis and *training* references.

Evaluation references (``m_serial``, ``curve``, ``reversal_sine``, ``s_curve``, ``circle``)
never appear here: every reference comes from the seeded ``random`` training mixture
(:data:`fricbench.trajectories.TRAINING_SET`).
"""

from __future__ import annotations

import numpy as np

from fricbench._validation import check_int, check_positive
from fricbench.axis import Axis
from fricbench.gym.specs import get_spec
from fricbench.gym.task import TaskConfig
from fricbench.trajectories import TRAINING_SET, Reference, make_trajectory

__all__ = ["env_setup", "training_references"]


def env_setup(env_id: str) -> tuple[Axis, TaskConfig]:
    """Nominal axis and task of the registered env ``env_id``.

    Raises
    ------
    gymnasium.error.NameNotFound
        For an unknown id (the message lists near matches).
    """
    if not isinstance(env_id, str):
        raise TypeError(f"env_id={env_id!r}: expected a registered env id string")
    spec = get_spec(env_id)
    return spec.axis, spec.task


def training_references(n: int, *, seed: int, duration: float = 20.0,
                        ts: float = 1.0e-3) -> list[Reference]:
    """``n`` references of the seeded ``random`` training mixture.

    Parameters
    ----------
    n : int
        Number of references.
    seed : int
        Root seed; reference ``i`` uses the ``i``-th state of ``SeedSequence(seed)``.
    duration : float
        Length of each reference, s.
    ts : float
        Sample time, s (the axis controller's).
    """
    check_int("n", n, 1, 10_000)
    check_int("seed", seed, 0)
    check_positive("duration", duration, "s")
    (traj_id,) = TRAINING_SET
    seeds = np.random.SeedSequence(seed).generate_state(n, dtype=np.uint32)
    return [make_trajectory(traj_id, seed=int(s) & 0x7FFFFFFF, duration=float(duration),
                            ts=float(ts)) for s in seeds]
