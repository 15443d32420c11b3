"""Compensator.batch: each row acts exactly as its member alone, for every compensator.

The vectorised batches (``kalman``, ``rl-sac``, ``rl-ppo``, ``rl-residual``) step every row in
one numpy call; that is only allowed when a row's numbers do not depend on the other rows, so
the policy network and the observer bank are checked for it on their own, and every batch is
checked against its members' own ``act``, bit for bit, on the benchmark's drawn plants.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fricbench.axis.variation import nominal_told
from fricbench.bench.runner import bench_env
from fricbench.compensators import (
    Compensator,
    CompensatorBatch,
    compensator_registry,
    make_compensator,
)
from fricbench.compensators.residual_base import ObserverBank
from fricbench.compensators.rl_policy import load_policy
from fricbench.gym import ServoAxisEnv, get_spec

PAPER, CIRCLE = "fricbench/PaperAxis-v0", "fricbench/CircleContouring-v0"
VECTORISED = ("kalman", "rl-sac", "rl-ppo", "rl-residual", "ekf")
POLICIES = sorted(Path(__file__).resolve().parents[2].joinpath("fricbench", "policies")
                  .glob("*.json"))
# the references of up to three members of a batch (another per member: each is read from
# its own reset state); the two-axis env has one trajectory
TRAJECTORIES = {PAPER: ("s_curve", "reversal_sine", "m_serial"), CIRCLE: ("circle",) * 3}


def test_shipped_policies_found() -> None:
    assert {p.stem for p in POLICIES} >= {"rl-sac", "rl-ppo", "rl-residual"}


@pytest.mark.parametrize("path", POLICIES, ids=lambda p: p.stem)
def test_policy_rows_do_not_depend_on_the_batch(path: Path) -> None:
    """Each row of a call on 1..33 rows is what that row alone gives, bit for bit."""
    pol = load_policy(path)
    rng = np.random.default_rng(11)
    obs = rng.normal(scale=2.0, size=(64, pol.spec.obs_dim))
    alone = np.concatenate([pol(obs[i:i + 1]) for i in range(len(obs))])
    for n in [*range(1, 34), 64]:
        np.testing.assert_array_equal(pol(obs[:n]), alone[:n], err_msg=f"n={n}")
    # and wherever the row sits
    perm = rng.permutation(33)
    np.testing.assert_array_equal(pol(obs[perm]), alone[perm])


def test_observer_bank_rows_do_not_depend_on_the_bank() -> None:
    """A bank of n rows steps each row as a bank of that row alone, bit for bit, also when
    rows start their episodes at different samples."""
    axis = nominal_told(get_spec(PAPER).axis)
    rng = np.random.default_rng(5)
    n_max, steps = 33, 60
    x0, v0 = rng.normal(scale=1e-3, size=n_max), rng.normal(scale=1e-2, size=n_max)
    z = x0 + rng.normal(scale=1e-6, size=(steps, n_max)).cumsum(axis=0)
    force = rng.normal(scale=200.0, size=(steps, n_max))
    alone = []
    for i in range(n_max):
        bank = ObserverBank(axis, 1, max_force=600.0)
        bank.reset(np.array([0]), x0[i:i + 1], v0[i:i + 1])
        d = []
        for k in range(steps):
            bank.step(z[k, i:i + 1], force[k, i:i + 1])
            d.append(bank.d_hat.copy())
        alone.append(np.concatenate(d))
    expected = np.array(alone).T  # (steps, n_max)
    for n in range(1, n_max + 1):
        bank = ObserverBank(axis, n, max_force=600.0)
        bank.reset(np.arange(n), x0[:n], v0[:n])
        for k in range(steps):
            bank.step(z[k, :n], force[k, :n])
            np.testing.assert_array_equal(bank.d_hat, expected[k, :n], err_msg=f"n={n} k={k}")
    # stacked banks and row subsets give the same numbers
    parts = []
    for i in range(3):
        b = ObserverBank(axis, 1, max_force=600.0)
        b.reset(np.array([0]), x0[i:i + 1], v0[i:i + 1])
        parts.append(b)
    stacked = ObserverBank.stack(parts)
    for k in range(steps):
        stacked.step(z[k, 1:2], force[k, 1:2], rows=np.array([1]))
        stacked.step(z[k, [0, 2]], force[k, [0, 2]], rows=np.array([0, 2]))
        np.testing.assert_array_equal(stacked.d_hat, expected[k, :3])


def test_stack_refuses_other_filters() -> None:
    axis = nominal_told(get_spec(PAPER).axis)
    with pytest.raises(ValueError, match="banks"):
        ObserverBank.stack([ObserverBank(axis, 1), ObserverBank(axis, 1, bandwidth=500.0)])
    with pytest.raises(ValueError, match="banks"):
        ObserverBank.stack([])


def _episodes(env_id: str, members: list[Compensator], twins: list[Compensator],
              trajectories: tuple[str, ...]) -> tuple[list[ServoAxisEnv], list[np.ndarray]]:
    """Reset one env per member on its seed's plant (seed = index) and each member and its
    twin on that env's episode, as the benchmark does; the envs and first observations."""
    envs, first = [], []
    for s, (m, t) in enumerate(zip(members, twins, strict=True)):
        env = bench_env(env_id, m, seed=s)
        obs, _ = env.reset(seed=s, options={"trajectory": trajectories[s]})
        ctx = env.episode_context()
        m.reset(ctx, seed=s + 7919)
        t.reset(ctx, seed=s + 7919)
        envs.append(env)
        first.append(obs)
    return envs, first


def _check_batch(env_id: str, members: list[Compensator], twins: list[Compensator],
                 steps: int, trajectories: tuple[str, ...]) -> CompensatorBatch:
    """Step each env with its member's own act and the batch of the twins (fresh copies) on
    the stacked observations; the actions must be bit-identical at every step."""
    envs, obs = _episodes(env_id, members, twins, trajectories)
    batch = type(twins[0]).batch(twins)
    assert len(batch) == len(members)
    for k in range(steps):
        own = np.stack([m.act(o) for m, o in zip(members, obs, strict=True)])
        together = batch.act(np.stack(obs))
        assert together.dtype == own.dtype == np.float32
        assert np.array_equal(together, own), (k, together, own)
        observers = getattr(batch, "_observers", None)
        if observers is not None:  # the float64 estimates too, not only the float32 actions
            own_d = [m._observers.bank.d_hat for m in members]
            np.testing.assert_array_equal(observers.bank.d_hat, np.concatenate(own_d))
        truncated = False
        for i, env in enumerate(envs):
            obs[i], _, _, trunc_i, _ = env.step(own[i])
            truncated = truncated or trunc_i
        if truncated:
            break
    return batch


_FITTED: dict[tuple[str, str], Compensator] = {}


def _fitted(cid: str, env_id: str = PAPER, **kwargs: Any) -> Compensator:
    """``cid`` fitted once per env (seed 3, with the constructor keywords ``kwargs``) and kept
    for copies."""
    key = (cid, env_id + repr(sorted(kwargs.items())))
    if key not in _FITTED:
        comp = make_compensator(cid, **kwargs)
        try:
            comp.fit(env_id, seed=3)
        except ImportError as exc:  # an optional dependency (the predictors) missing
            pytest.skip(f"{cid}: {exc}")
        _FITTED[key] = comp
    return _FITTED[key]


def _copies(comp: Compensator, n: int) -> list[Compensator]:
    return [copy.deepcopy(comp) for _ in range(n)]


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("env_id", [PAPER, CIRCLE])
@pytest.mark.parametrize("cid", VECTORISED)
def test_vectorised_batch_is_each_member(cid: str, env_id: str, n: int) -> None:
    """One numpy call for every row, bit-identical to each member's own act, on the drawn
    plants of seeds 0..n-1 (each member on its own reference where the env has several)."""
    comp = _fitted(cid, env_id)
    batch = _check_batch(env_id, _copies(comp, n), _copies(comp, n), 300,
                         TRAJECTORIES[env_id][:n])
    assert type(batch) is not CompensatorBatch  # the vectorised path, not the default


def test_members_that_differ_act_row_by_row() -> None:
    """Members with other settings (kalman's bandwidth) or policies (rl-sac beside rl-ppo,
    one class) get the default batch, still exact."""
    kal = [make_compensator("kalman"), make_compensator("kalman", bandwidth=500.0),
           make_compensator("kalman")]
    twins = copy.deepcopy(kal)
    batch = _check_batch(PAPER, kal, twins, 100, TRAJECTORIES[PAPER])
    assert type(batch) is CompensatorBatch
    rl = [_fitted("rl-sac"), _fitted("rl-ppo")]
    batch = _check_batch(PAPER, copy.deepcopy(rl), copy.deepcopy(rl), 100,
                         TRAJECTORIES[PAPER][:2])
    assert type(batch) is CompensatorBatch


@pytest.mark.parametrize("cid", sorted(compensator_registry.ids()))
def test_every_compensator_batch_is_each_member(cid: str,
                                                light: dict[str, dict[str, Any]]) -> None:
    """Every registered compensator, vectorised or row by row (the default), on two seeds'
    plants of the single-axis env (light fits; the vectorised ones are also run above)."""
    comp = _fitted(cid, **light.get(cid, {}))
    batch = _check_batch(PAPER, _copies(comp, 2), _copies(comp, 2), 120,
                         TRAJECTORIES[PAPER][:2])
    assert (type(batch) is not CompensatorBatch) == (cid in VECTORISED)
