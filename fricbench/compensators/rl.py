"""``rl-sac``, ``rl-ppo``: stable-baselines3 agents trained on the randomised-friction env.

The agents are trained once (``fricbench train rl-sac ...``, see
:mod:`fricbench.compensators.train`) on ``fricbench/RandomFriction-v0``: friction redrawn
every episode, seeded ``random`` training references only. The shipped policies in
``fricbench/policies/`` are the deterministic actors as plain weights plus a JSON
(:mod:`fricbench.compensators.rl_policy`); :meth:`RLCompensator.fit` only loads and checks
them (no retraining in the benchmark).

On a D-axis env (the two-axis circle) the single-axis policy acts on each axis's block of the
observation (the appended contour error is not used).
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import ClassVar

import numpy as np

from fricbench._validation import check_choice
from fricbench.axis import Axis
from fricbench.compensators.base import (
    Compensator,
    CompensatorBatch,
    CompensatorError,
    EpisodeContext,
)
from fricbench.compensators.rl_policy import NumpyPolicy, load_policy
from fricbench.compensators.training_data import env_setup
from fricbench.gym.task import n_features

__all__ = ["RLCompensator", "load_policy_for", "shipped_policy"]


def shipped_policy(comp_id: str) -> Path:
    """Path of the shipped policy JSON of ``comp_id`` (``fricbench/policies/<id>.json``)."""
    return Path(str(resources.files("fricbench").joinpath("policies", f"{comp_id}.json")))


def load_policy_for(comp: Compensator, path: Path, env_id: str, *, algo: str | None = None
                    ) -> tuple[NumpyPolicy, int]:
    """The policy at ``path``, checked to be of ``algo`` (when given) and of ``comp``'s action
    mode, and the number of observation features per axis of ``env_id``.

    Raises
    ------
    CompensatorError
        Naming the file, when it is missing or corrupt, from another algorithm or trained for
        another action mode.
    """
    pol = load_policy(path)
    spec = pol.spec
    if algo is not None and spec.algo != algo:
        raise CompensatorError(f"{path}: a {spec.algo!r} policy; {comp.id} expects {algo!r}")
    if spec.action_mode != comp.action_mode:
        raise CompensatorError(f"{path}: trained for {spec.action_mode!r} actions; {comp.id} "
                               f"acts in {comp.action_mode!r} mode")
    _, task = env_setup(env_id)
    return pol, n_features(task.observation)


class RLCompensator(Compensator):
    """A trained actor network acting in the env loop.

    Registered variants: ``rl-sac`` (``algo="sac"``: soft actor-critic, deterministic actor
    ``tanh(mu(obs))``) and ``rl-ppo`` (``algo="ppo"``: proximal policy optimisation, actor mean
    clipped to [-1, 1]), both trained with stable-baselines3.

    Parameters
    ----------
    algo : {"sac", "ppo"}
        The algorithm the policy was trained with (checked against the policy file).
    policy : str or Path or None
        Policy JSON (weights next to it); ``None``: the shipped policy ``rl-<algo>``.

    Attributes
    ----------
    policy_ : NumpyPolicy
        The loaded actor (after :meth:`fit`).
    """

    action_mode: ClassVar[str] = "force"
    learns: ClassVar[bool] = True
    category: ClassVar[str] = "policy"

    def __init__(self, *, algo: str = "sac", policy: str | Path | None = None) -> None:
        super().__init__()
        check_choice("algo", algo, ("sac", "ppo"))
        self.algo = algo
        self.id = f"rl-{algo}"
        if policy is not None and not isinstance(policy, (str, Path)):
            raise TypeError(f"policy={policy!r}: expected a path to a policy JSON or None")
        self.policy = policy

    @property
    def policy_path(self) -> Path:
        """The policy JSON this compensator loads."""
        return shipped_policy(f"rl-{self.algo}") if self.policy is None else Path(self.policy)

    def fit(self, env_id: str, *, seed: int = 0, axis: Axis | None = None) -> RLCompensator:
        """Load the trained policy and check it fits ``env_id`` (no training here; ``axis``,
        the machine, is not used: the policy was learned offline).

        Raises
        ------
        CompensatorError
            Naming the file, when it is missing, corrupt, from another algorithm, or built for
            another observation layout or action mode.
        """
        self.policy_ = self._load(env_id)
        self._fitted = True
        return self

    def check_setup(self, env_id: str) -> None:
        """Load the policy file and check it fits ``env_id`` (what :meth:`fit` does, without
        keeping it).

        Raises
        ------
        CompensatorError
            As :meth:`fit`.
        """
        self._load(env_id)

    def _load(self, env_id: str) -> NumpyPolicy:
        path = self.policy_path
        pol, nf = load_policy_for(self, path, env_id, algo=self.algo)
        spec = pol.spec
        if spec.obs_dim != nf or spec.act_dim != 1:
            raise CompensatorError(f"{path}: obs_dim={spec.obs_dim}, act_dim={spec.act_dim}; "
                                   f"{env_id} has {nf} features and 1 action per axis")
        return pol

    def _reset(self, context: EpisodeContext, seed: int | None) -> None:
        pol: NumpyPolicy = self.policy_
        nf = n_features(context.task.observation)
        if nf != pol.spec.obs_dim:
            raise CompensatorError(f"{self.policy_path}: obs_dim={pol.spec.obs_dim} but the "
                                   f"episode's env has {nf} features per axis")
        self._nf = nf
        # a unit action means spec.action_scale in training: keep the physical output
        self._gain = pol.spec.action_scale / context.task.action_scale

    def _act(self, observation: np.ndarray) -> np.ndarray:
        return _policy_action(self.policy_, self._nf, self.context.n_axes,
                              np.array([self._gain]), observation[None])

    @classmethod
    def batch(cls, members: Sequence[Compensator]) -> CompensatorBatch:
        """One policy call over every axis block of every member's observation; members
        with different policies act row by row (the default)."""
        # checks the members: one class, each reset, one number of axes
        default = CompensatorBatch(members)
        comps = [m for m in members if isinstance(m, RLCompensator)]
        first = comps[0] if len(comps) == len(members) else None
        if first is None or not all(c._nf == first._nf and first.policy_.same_as(c.policy_)
                                    for c in comps):
            return default
        return _PolicyBatch(comps, first.policy_, first._nf,
                            np.array([c._gain for c in comps]))


def _policy_action(policy: NumpyPolicy, nf: int, d: int, gain: np.ndarray,
                   observations: np.ndarray) -> np.ndarray:
    """Actions (N * D,) of the single-axis ``policy`` on each axis block of observations
    (N, obs_dim), times each episode's ``gain`` (N,)."""
    n = observations.shape[0]
    rows = observations[:, : d * nf].reshape(n * d, nf)
    return policy(rows)[:, 0] * np.repeat(gain, d)


class _PolicyBatch(CompensatorBatch):
    """``rl-sac``/``rl-ppo`` episodes acted for by one policy call per sample."""

    def __init__(self, members: Sequence[Compensator], policy: NumpyPolicy, nf: int,
                 gain: np.ndarray) -> None:
        super().__init__(members)
        self._policy, self._nf, self._gain = policy, nf, gain

    def _act_rows(self, observations: np.ndarray) -> np.ndarray:
        return _policy_action(self._policy, self._nf, self.n_axes, self._gain, observations)
