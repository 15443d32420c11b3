"""``rl-residual``: a learned force added to the ``kalman`` disturbance observer.

RL friction compensation that has worked on real axes runs as a *residual*: a classical
controller or observer does the bulk of the work and the policy learns only what it misses.
Here the base is the ``kalman`` disturbance observer (:mod:`fricbench.compensators.kalman`),
chosen over ``friction-ff`` because it needs no fitting (nothing per machine to get wrong at
training time), adapts online to whatever plant it runs on, and is defined for every axis an
episode may draw. The compensation force is::

    u = clip(-gain d_hat, +-F_max) + s_r pi(o, d_hat / F_s)

with ``d_hat`` the observer's disturbance estimate (:class:`~fricbench.compensators.
residual_base.ObserverBank`, the same filter the policy was trained on top of, see
:mod:`fricbench.compensators.residual_env`), ``pi`` the policy's deterministic action in
[-1, 1] on the env's observation plus ``d_hat`` scaled by the observation's force scale, and
``s_r`` the residual's force per unit. The total is clipped to the env's action range.

The policy reads every force in units of the env's observation force scale ``F_s`` (the motor
force column and ``d_hat / F_s``), so its residual is read in the same unit: ``s_r`` is the
policy JSON's ``action_scale`` (newtons on its training env) times ``F_s / F_s,train``. On an
env of the training env's size the ratio is exactly 1 (the JSON's newtons); on a smaller axis
the residual shrinks with everything else the policy sees (EMPS-v0: ``F_s`` 152 N against
1000 N, a 400 N residual would span ten times the drive's 40 N range). A policy whose
training env is not registered here keeps its JSON's newtons.

The shipped policy (``fricbench/policies/rl-residual.*``) was trained by
``fricbench train rl-residual`` on ``fricbench/RandomFriction-v0``'s nominal axis with a plant
drawn per episode from the benchmark's distribution (:data:`fricbench.axis.variation.
BENCH_VARIATION`: friction level, static excess above Coulomb, Stribeck velocity, mass and
damping; encoder and current noise), on seeded ``random`` training references only; its JSON
records the distribution under ``training.residual``.

A policy acts only within what it was trained on: the training env's loop (its controller, the
integration substeps aside) and its mass and damping within the plants' spread (the JSON's
``training.residual.sigma``, truncated at :data:`fricbench.axis.variation.TRUNCATION` sigmas). On
another axis (:func:`residual_scope` says why: the EMPS twin's P loop without feedforward and
95 kg, against the paper axis's cascade and 400 kg) the compensator runs its base alone
(``residual_off_`` holds the reason, :meth:`ResidualRLCompensator.env_note` gives it to the
leaderboard): a residual learnt on another loop made the EMPS twin's error larger than the base
alone (653.4 against 649.1 um on m_serial, median of 10 plants).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from fricbench.axis import Axis
from fricbench.compensators.base import (
    Compensator,
    CompensatorBatch,
    CompensatorError,
    EpisodeContext,
)
from fricbench.compensators.kalman import _KalmanBatch, _observer_action
from fricbench.compensators.residual_base import EpisodeObservers
from fricbench.compensators.rl import load_policy_for, shipped_policy
from fricbench.compensators.rl_policy import NumpyPolicy
from fricbench.compensators.training_data import env_setup
from fricbench.gym.task import n_features

__all__ = ["ResidualRLCompensator", "base_settings", "residual_scope"]


def base_settings(training: Mapping[str, Any], path: str | Path) -> tuple[float, float]:
    """``(bandwidth, gain)`` of the base recorded in a residual policy's ``training`` entry.

    Raises
    ------
    CompensatorError
        Naming ``path``, when the entry is missing or is not a ``kalman`` base.
    """
    res = training.get("residual")
    base = res.get("base") if isinstance(res, Mapping) else None
    if not isinstance(base, Mapping) or base.get("id") != "kalman":
        raise CompensatorError(f"{path}: training.residual.base={base!r}: expected the kalman "
                               "base a residual policy was trained on (not a residual policy?)")
    vals = []
    for key in ("bandwidth", "gain"):
        val = base.get(key)
        if isinstance(val, bool) or not isinstance(val, (int, float)) \
                or not np.isfinite(val) or val < 0 or (key == "bandwidth" and val == 0):
            raise CompensatorError(f"{path}: training.residual.base.{key}={val!r}: expected "
                                   "a positive number")
        vals.append(float(val))
    return vals[0], vals[1]


def _loop_text(axis: Axis) -> str:
    c = axis.controller
    if c.law == "linear":
        return "a linear control law"
    return (f"a cascade, kp={c.kp:g} 1/s, kvff={c.kvff:g}, kv={c.kv:g} A s/m, ti={c.ti:g} s, "
            f"kt={c.kt:g} N/A")


def residual_scope(train_axis: Axis, axis: Axis, sigma: Mapping[str, Any]) -> str:
    """Why a residual trained around ``train_axis`` does not apply to ``axis``; ``""`` when
    it does.

    It applies when ``axis`` runs the training axis's controller (the integration substeps
    aside) and its mass and damping lie within the training plants' spread: factors
    ``exp(+-TRUNCATION sigma)`` of the training axis's, ``sigma`` the JSON's
    ``training.residual.sigma`` (a missing entry: no spread).

    Parameters
    ----------
    train_axis : Axis
        Nominal axis of the policy's training env.
    axis : Axis
        Nominal axis of the env it is to run on.
    sigma : mapping
        Log-normal sigmas of the training plants (``mass``, ``damping``).
    """
    from fricbench.axis.variation import TRUNCATION

    reasons = []
    if replace(axis.controller, n_substeps=train_axis.controller.n_substeps) \
            != train_axis.controller:
        reasons.append(f"its loop is {_loop_text(axis)}, the policy's "
                       f"{_loop_text(train_axis)}")
    for name, unit in (("mass", "kg"), ("damping", "N s/m")):
        trained, here = getattr(train_axis.mechanics, name), getattr(axis.mechanics, name)
        spread = math.exp(TRUNCATION * float(sigma.get(name, 0.0)))
        if not trained / spread <= here <= trained * spread:
            reasons.append(f"its {name} {here:.4g} {unit} lies outside the training plants' "
                           f"{trained / spread:.4g} .. {trained * spread:.4g} {unit}")
    return "; ".join(reasons)


class ResidualRLCompensator(Compensator):
    """The ``kalman`` observer's force plus a trained policy's residual force.

    Parameters
    ----------
    policy : str or Path or None
        Policy JSON of a residual policy (weights next to it); ``None``: the shipped
        ``rl-residual`` policy.

    Attributes
    ----------
    policy_ : NumpyPolicy
        The loaded actor (after :meth:`fit`).
    bandwidth_, gain_ : float
        The base observer's settings, read from the policy (those it was trained on).
    residual_off_ : str
        Why the residual is off on the fitted env, which then gets the base alone
        (:func:`residual_scope`); ``""`` when the residual acts.
    """

    id = "rl-residual"
    action_mode: ClassVar[str] = "force"
    learns: ClassVar[bool] = True
    category: ClassVar[str] = "policy"

    def __init__(self, *, policy: str | Path | None = None) -> None:
        super().__init__()
        if policy is not None and not isinstance(policy, (str, Path)):
            raise TypeError(f"policy={policy!r}: expected a path to a policy JSON or None")
        if isinstance(policy, str) and not policy:
            raise ValueError("policy='': expected a path to a policy JSON or None")
        self.policy = policy

    @property
    def policy_path(self) -> Path:
        """The policy JSON this compensator loads."""
        return shipped_policy("rl-residual") if self.policy is None else Path(self.policy)

    def fit(self, env_id: str, *, seed: int = 0,
            axis: Axis | None = None) -> ResidualRLCompensator:
        """Load the trained residual policy and check it fits ``env_id`` (no training here;
        ``axis`` is not used: the policy was learned offline on drawn plants).

        Raises
        ------
        CompensatorError
            Naming the file, when it is missing or corrupt, acts in another mode, was not
            trained as a residual, or was built for another observation layout.
        """
        pol, (self.bandwidth_, self.gain_) = self._load(env_id)
        spec = pol.spec
        self.policy_: NumpyPolicy = pol
        self.residual_off_ = self._scope(env_id)
        try:  # the force unit the policy learned in (see the module docstring)
            self.train_force_scale_: float | None = \
                env_setup(spec.env_id)[1].observation.force_scale
        except (KeyError, ValueError):
            self.train_force_scale_ = None
        self._fitted = True
        return self

    def check_setup(self, env_id: str) -> None:
        """Load the residual policy file and check it fits ``env_id`` (what :meth:`fit` does,
        without keeping it).

        Raises
        ------
        CompensatorError
            As :meth:`fit`.
        """
        self._load(env_id)

    def _load(self, env_id: str) -> tuple[NumpyPolicy, tuple[float, float]]:
        """The policy and its base's ``(bandwidth, gain)``, checked against ``env_id``."""
        path = self.policy_path
        pol, nf = load_policy_for(self, path, env_id)
        spec = pol.spec
        base = base_settings(spec.training, path)
        if spec.obs_dim != nf + 1 or spec.act_dim != 1:
            raise CompensatorError(f"{path}: obs_dim={spec.obs_dim}, act_dim={spec.act_dim}; "
                                   f"{self.id} on {env_id} needs {nf + 1} features (the env's "
                                   f"{nf} and the base's estimate) and 1 action per axis")
        return pol, base

    def _scope(self, env_id: str) -> str:
        """:func:`residual_scope` of the loaded policy on ``env_id`` (``""`` when the policy's
        training env is not registered here: nothing to compare with)."""
        spec = self.policy_.spec
        try:
            train_axis = env_setup(spec.env_id)[0]
        except (KeyError, ValueError):
            return ""
        res = spec.training.get("residual")
        sigma = res.get("sigma", {}) if isinstance(res, Mapping) else {}
        return residual_scope(train_axis, env_setup(env_id)[0],
                              sigma if isinstance(sigma, Mapping) else {})

    def env_note(self, env_id: str) -> str:
        """Why this compensator runs its base alone on ``env_id`` (``""`` when its residual
        acts there); loads the policy, trains nothing."""
        if getattr(self, "policy_", None) is None:
            self.policy_ = load_policy_for(self, self.policy_path, env_id)[0]
        reason = self._scope(env_id)
        if not reason:
            return ""
        return (f"`{self.id}` is its base `kalman` alone here: its policy was trained on "
                f"`{self.policy_.spec.env_id}` plants, and this env's axis is outside them "
                f"({reason})")

    def _reset(self, context: EpisodeContext, seed: int | None) -> None:
        nf = n_features(context.task.observation)
        if nf + 1 != self.policy_.spec.obs_dim:
            raise CompensatorError(f"{self.policy_path}: obs_dim={self.policy_.spec.obs_dim} "
                                   f"but the episode's env has {nf} features per axis (+1)")
        self._nf = nf
        # the base exactly as kalman builds it: its filter, clipped at the env's action scale
        self._observers = EpisodeObservers(context, bandwidth=self.bandwidth_, gain=self.gain_)

    def _act(self, observation: np.ndarray) -> np.ndarray:
        if self.residual_off_:
            return _observer_action(self._observers, observation[None])
        return _residual_action(self._observers, self.policy_, self._nf, observation[None],
                                self.train_force_scale_)

    @classmethod
    def batch(cls, members: Sequence[Compensator]) -> CompensatorBatch:
        """One observer bank and one policy call over every axis of every member's episode;
        members with different policies, bases or nominal axes act row by row (the
        default)."""
        # checks the members: one class, each reset, one number of axes
        default = CompensatorBatch(members)
        comps = [m for m in members if isinstance(m, ResidualRLCompensator)]
        first = comps[0] if len(comps) == len(members) else None
        if first is None or not all(c._nf == first._nf and first.policy_.same_as(c.policy_)
                                    and c.train_force_scale_ == first.train_force_scale_
                                    and c.residual_off_ == first.residual_off_
                                    for c in comps):
            return default
        try:
            observers = EpisodeObservers.stack([c._observers for c in comps])
        except ValueError:
            return default
        if first.residual_off_:
            return _KalmanBatch(comps, observers)
        return _ResidualBatch(comps, observers, first.policy_, first._nf,
                              first.train_force_scale_)


def _residual_action(observers: EpisodeObservers, policy: NumpyPolicy, nf: int,
                     observations: np.ndarray, train_force_scale: float | None) -> np.ndarray:
    """Step the base on observations (N, obs_dim); actions (N * D,) of base plus residual."""
    observers.step(observations)
    bank, n, d = observers.bank, observations.shape[0], observers.n_axes
    rows = observations[:, : d * nf].reshape(n * d, nf)
    aug = np.column_stack([rows, bank.d_hat / observers.force_scale])
    # u = clip(-gain d_hat, +-F_max) + s_r pi(o, d_hat / F_s)
    # s_r in the env's force unit (exactly the JSON's newtons when F_s is the training env's)
    s_r = policy.spec.action_scale if train_force_scale is None \
        else policy.spec.action_scale * (observers.force_scale / train_force_scale)
    residual = policy(aug)[:, 0] * s_r
    return (bank.force() + residual) / observers.action_scale


class _ResidualBatch(CompensatorBatch):
    """``rl-residual`` episodes: one observer bank, one policy call per sample."""

    def __init__(self, members: Sequence[Compensator], observers: EpisodeObservers,
                 policy: NumpyPolicy, nf: int, train_force_scale: float | None) -> None:
        super().__init__(members)
        self._observers, self._policy, self._nf = observers, policy, nf
        self._train_force_scale = train_force_scale

    def _act_rows(self, observations: np.ndarray) -> np.ndarray:
        return _residual_action(self._observers, self._policy, self._nf, observations,
                                self._train_force_scale)
