"""ekf's bank: against filterpy's EKF, rows independent of the batch, batch = members' own act.

Run as a script for the timings that justify the bank (filterpy's EKF per axis against the
bank; one batch act of N episodes against N acts)::

    PYTHONPATH=. python tests/compensators/test_ekf_batch.py
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

import fricbench  # noqa: F401
from fricbench.bench.runner import bench_env
from fricbench.compensators import EpisodeContext, make_compensator
from fricbench.compensators.base import CompensatorBatch
from fricbench.compensators.ekf import (
    EKFBank,
    EKFModel,
    ExtendedFrictionObserver,
    ekf_model,
    ekf_transition,
)
from fricbench.gym import ServoAxisEnv, get_spec

PAPER = "fricbench/PaperAxis-v0"
CIRCLE = "fricbench/CircleContouring-v0"


# -- the reference: one filterpy ExtendedKalmanFilter per axis, scalar math -----------------------
# (the filter recursion the bank replaced, kept here as the yardstick)

def _ref_shape(v: float, model: EKFModel) -> tuple[float, float, float]:
    inv_eps = 1.0 / model.eps
    t = math.tanh(v * inv_eps)
    sech2 = 1.0 - t * t
    t1 = sech2 * inv_eps
    t2 = -2.0 * t * sech2 * inv_eps * inv_eps
    h, h1, h2 = 1.0, 0.0, 0.0
    if model.vs > 0.0 and model.rho != 1.0:
        inv_vs2 = 1.0 / (model.vs * model.vs)
        r2 = v * v * inv_vs2
        if r2 < 40.0:
            ex = (model.rho - 1.0) * math.exp(-r2)
            h = 1.0 + ex
            h1 = -2.0 * v * inv_vs2 * ex
            h2 = ex * (4.0 * r2 - 2.0) * inv_vs2
    return h * t, h1 * t + h * t1, h2 * t + 2.0 * h1 * t1 + h * t2


class _RefFilter(ExtendedKalmanFilter):  # type: ignore[misc]
    """filterpy's EKF (its predict: ``P = F P F' + Q``) with the model's transition."""

    def __init__(self, model: EKFModel) -> None:
        super().__init__(dim_x=4, dim_z=1, dim_u=1)
        self.model = model
        self.F = np.diag([1.0, 1.0, 1.0, model.decay])
        self.v_adapt = 3.0 * model.eps

    def predict_x(self, u: float = 0.0) -> None:
        # the model's transition is the module's (its Jacobian is checked against finite
        # differences in test_ekf.py): the yardstick here is the filter recursion around it
        self.x = ekf_transition(self.x, float(u), self.model, self.F)

    def update_position(self, z: float) -> None:
        # filterpy's Joseph-form update for H = [1 0 0 0], the level held below 3 eps
        p, r = self.P, float(self.R[0, 0])
        k = p[:, :1] / (p[0, 0] + r)
        if abs(self.x[1, 0]) < self.v_adapt:
            k[2, 0] = 0.0
        self.x = self.x + k * (z - self.x[0, 0])
        i_kh = np.eye(4)
        i_kh[:, :1] -= k
        self.P = i_kh @ p @ i_kh.T + r * (k @ k.T)


class FilterpyEKF(ExtendedFrictionObserver):
    """``ekf`` as it was: one filterpy ``ExtendedKalmanFilter`` per axis, stepped in Python."""

    @classmethod
    def batch(cls, members: Sequence[Any]) -> CompensatorBatch:
        return CompensatorBatch(members)  # row by row, as every compensator without a bank

    def _reset(self, context: EpisodeContext, seed: int | None) -> None:
        super()._reset(context, seed)  # the bank's x0, P0, Q, R: read them back
        bank = self._rows.bank
        self._model = ekf_model(context.nominal_axis, self.eps, self.residual_time)
        self._ref: list[_RefFilter] = []
        for i in range(context.n_axes):
            kf = _RefFilter(self._model)
            kf.x, kf.P = bank.x[i].reshape(4, 1).copy(), bank.P[i].copy()
            kf.Q, kf.R = bank.Q[i].copy(), np.array([[bank.r[i]]])
            self._ref.append(kf)

    def _act(self, observation: np.ndarray) -> np.ndarray:
        k = min(self._k, self._xref.shape[1] - 1)
        out = np.empty(len(self._ref))
        for i, kf in enumerate(self._ref):
            e_col, f_col = self._cols[i]
            if self._k > 0:
                kf.predict(u=observation[f_col] * self._f_scale)
            kf.update_position(self._xref[i, k] - observation[e_col] * self._e_scale)
            v, c, d = float(kf.x[1, 0]), float(kf.x[2, 0]), float(kf.x[3, 0])
            u = self.gain * (c * _ref_shape(v, self._model)[0] + self._model.fv * v - d)
            out[i] = min(max(u, -self._limit), self._limit) / self._scale
        self._k += 1
        return out


# -- helpers ------------------------------------------------------------------------------------

def _episode(env_id: str, seed: int, trajectory: str, comps: Sequence[Any]
             ) -> tuple[ServoAxisEnv, np.ndarray]:
    """The benchmark env of ``seed`` reset on ``trajectory``, each of ``comps`` reset on it."""
    env = bench_env(env_id, comps[0], seed)
    obs, _ = env.reset(seed=seed, options={"trajectory": trajectory})
    for c in comps:
        c.reset(env.episode_context(), seed=seed)
    return env, obs


# -- the bank against filterpy ------------------------------------------------------------------

@pytest.mark.parametrize(("seed", "trajectory"), [(0, "s_curve"), (2, "m_serial")])
def test_bank_follows_filterpy_on_an_episode(seed: int, trajectory: str) -> None:
    """Fed the same observations over a whole benchmark episode (the env driven by filterpy's
    actions), the bank's actions (float64, before the float32 cast) agree with filterpy's to
    1e-10 of full scale and its states to 1e-11 of their size (measured on PaperAxis-v0 seeds
    0, 4, 2, 7 on s_curve, reversal_sine, m_serial, curve: at most 1.2e-11 and 4.2e-13, the
    float32 actions equal at all 77304 steps; round-off of filterpy's BLAS products against
    the bank's written-out sums, amplified by the stiff law near v = 0); the float32 actions
    differ by at most one ulp."""
    ref, bank = FilterpyEKF(), ExtendedFrictionObserver()
    env, obs = _episode(PAPER, seed, trajectory, [ref, bank])
    worst_a, worst_a32, worst_x, n = 0.0, 0.0, np.zeros(4), 0
    size = np.array([1e-3, 1e-2, 100.0, 100.0])  # m, m/s, N, N: the state's scale
    while True:
        o = np.asarray(obs, dtype=np.float64)  # as act() passes it on
        a_ref, a_bank = np.asarray(ref._act(o)), np.asarray(bank._act(o))
        worst_a = max(worst_a, float(np.max(np.abs(a_ref - a_bank))))
        worst_a32 = max(worst_a32, float(np.max(np.abs(
            np.clip(a_ref, -1, 1).astype(np.float32) - np.clip(a_bank, -1, 1).astype(np.float32)))))
        x_ref = ref._ref[0].x[:, 0]
        dx = np.abs(x_ref - bank._rows.bank.x[0]) / np.maximum(np.abs(x_ref), size)
        worst_x = np.maximum(worst_x, dx)
        n += 1
        obs, _, _, truncated, _ = env.step(np.clip(a_ref, -1, 1).astype(np.float32))
        if truncated:
            break
    assert n > 2000
    assert worst_a <= 1e-10, worst_a
    assert worst_a32 <= float(np.spacing(np.float32(1.0))), worst_a32
    assert np.all(worst_x <= 1e-11), worst_x


def test_bank_step_matches_filterpy_step_to_round_off() -> None:
    """One predict and update from random states and covariances, stuck and sliding."""
    model = ekf_model(get_spec(PAPER).axis, residual_time=0.05)
    rng = np.random.default_rng(11)
    n = 40
    x0 = np.column_stack([rng.normal(0, 1e-3, n), rng.choice([-1, 1], n) * 10.0
                          ** rng.uniform(-6, -1, n), rng.uniform(250, 450, n),
                          rng.normal(0, 20, n)])
    a = rng.normal(size=(n, 4, 4)) * np.array([1e-7, 1e-4, 10.0, 10.0])
    p0 = a @ a.transpose(0, 2, 1) + np.diag([1e-14, 1e-8, 100.0, 100.0])
    q = np.diag([1e-16, 1e-10, 1e-1, 1e-2])
    force = rng.normal(0, 300, n)
    z = x0[:, 0] + rng.normal(0, 1e-6, n)
    bank = EKFBank([model] * n, np.broadcast_to(q, (n, 4, 4)), np.full(n, 1e-12), x0, p0)
    bank.predict(force)
    bank.update_position(z)
    for i in range(n):
        kf = _RefFilter(model)
        kf.x, kf.P, kf.Q, kf.R = x0[i].reshape(4, 1), p0[i].copy(), q, np.array([[1e-12]])
        kf.predict(u=force[i])
        kf.update_position(z[i])
        np.testing.assert_allclose(bank.x[i], kf.x[:, 0], rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(bank.P[i], kf.P, rtol=1e-6,
                                   atol=1e-9 * np.abs(kf.P).max())


# -- rows independent of the batch --------------------------------------------------------------

def _random_bank(n: int, seed: int) -> EKFBank:
    """``n`` rows in every regime (stuck, in the Stribeck dip, sliding) and with their own
    models (masses, Stribeck shapes, eps, a row without a Stribeck term)."""
    rng = np.random.default_rng(seed)
    models = [EKFModel(mass=rng.uniform(50, 200), damping=rng.uniform(0, 500), ts=1e-3,
                       rho=rng.choice([1.0, rng.uniform(1.1, 1.8)]),
                       vs=rng.choice([0.0, rng.uniform(1e-3, 5e-3)]), fv=rng.uniform(0, 50),
                       eps=rng.choice([1e-4, 3e-5]), fc=350.0, decay=math.exp(-1e-3 / 0.05))
              for _ in range(n)]
    x0 = np.column_stack([rng.normal(0, 1e-3, n), rng.choice([-1, 1], n) * 10.0
                          ** rng.uniform(-6, -1, n), rng.uniform(250, 450, n),
                          rng.normal(0, 20, n)])
    a = rng.normal(size=(n, 4, 4)) * np.array([1e-7, 1e-4, 10.0, 10.0])
    p0 = a @ a.transpose(0, 2, 1) + np.diag([1e-14, 1e-8, 100.0, 100.0])
    q = np.abs(rng.normal(size=(n, 1, 1))) * np.diag([1e-16, 1e-10, 1e-1, 1e-2])
    return EKFBank(models, q, rng.uniform(1e-13, 1e-11, n), x0, p0)


def _run(bank: EKFBank, forces: np.ndarray, zs: np.ndarray) -> list[np.ndarray]:
    out = []
    for f, z in zip(forces, zs, strict=True):
        bank.predict(f)
        bank.update_position(z)
        out.append(bank.friction_force())
    return out


def test_rows_do_not_depend_on_the_batch_size() -> None:
    """Rows [a, a + n) stepped alone give bit for bit what they give inside 33 rows, for
    n = 1..33 and offsets a (matmul would not: BLAS blocks by size)."""
    full = _random_bank(33, seed=2)
    rng = np.random.default_rng(3)
    forces = rng.normal(0, 300, (25, 33))
    zs = full.x[:, 0] + rng.normal(0, 1e-6, (25, 33))
    parts = [(a, n) for n in range(1, 34) for a in sorted({0, 33 - n, (33 - n) // 2})]
    alone = [EKFBank.concatenate([full.rows(slice(a, a + n))]) for a, n in parts]
    want = _run(full, forces, zs)
    for (a, n), bank in zip(parts, alone, strict=True):
        sl = slice(a, a + n)
        got = _run(bank, forces[:, sl], zs[:, sl])
        for g, w in zip(got, want, strict=True):
            assert np.array_equal(g, w[sl]), (a, n)
        assert np.array_equal(bank.x, full.x[sl]) and np.array_equal(bank.P, full.P[sl])


# -- the batch: row i is member i's own act, bit for bit ----------------------------------------

def _check_batch(env_id: str, trajectory: str, seeds: Sequence[int], n_steps: int,
                 kwargs: Sequence[dict[str, float]] | None = None) -> None:
    kwargs = kwargs or [{}] * len(seeds)
    members = [make_compensator("ekf", **kw) for kw in kwargs]
    twins = [make_compensator("ekf", **kw) for kw in kwargs]  # step on their own
    envs, obs = [], []
    for seed, m, t in zip(seeds, members, twins, strict=True):
        env, o = _episode(env_id, seed, trajectory, [m, t])
        envs.append(env)
        obs.append(o)
    batch = ExtendedFrictionObserver.batch(members)
    assert type(batch) is not CompensatorBatch  # the bank, not the row-by-row default
    for step in range(n_steps):
        acts = batch.act(np.stack(obs))
        for i, (env, twin) in enumerate(zip(envs, twins, strict=True)):
            own = twin.act(obs[i])
            assert np.array_equal(acts[i], own), (env_id, step, i, acts[i], own)
            obs[i], *_ = env.step(acts[i])
    for m, t in zip(members, twins, strict=True):
        assert m.level_ == t.level_  # the members' filters are views of the batch's bank


@pytest.mark.parametrize("seeds", [[0], [0, 5, 9]])
def test_batch_is_the_members_own_act_paper_axis(seeds: list[int]) -> None:
    _check_batch(PAPER, "s_curve", seeds, 400)


def test_batch_rows_with_their_own_settings() -> None:
    """Members with different settings (gain, eps, residual) in one batch."""
    _check_batch(PAPER, "s_curve", [1, 1, 2], 300,
                 [{}, {"gain": 0.5, "eps": 3e-5}, {"residual_bandwidth": 100.0,
                                                   "max_force": 200.0}])


@pytest.mark.parametrize("seeds", [[0], [0, 5, 9]])
def test_batch_is_the_members_own_act_circle(seeds: list[int]) -> None:
    assert get_spec(CIRCLE).axis is not None
    _check_batch(CIRCLE, "circle", seeds, 400)


def test_batch_of_different_references() -> None:
    """Rows on references of different lengths: past its end a row reads its last sample,
    as its own act does."""
    members = [make_compensator("ekf") for _ in range(2)]
    twins = [make_compensator("ekf") for _ in range(2)]
    env, obs = _episode(PAPER, 0, "s_curve", [members[0], twins[0]])
    env2, obs2 = _episode(PAPER, 1, "reversal_sine", [members[1], twins[1]])
    lengths = [m._xref.shape[1] for m in members]
    assert lengths[0] != lengths[1]
    batch = ExtendedFrictionObserver.batch(members)
    rng = np.random.default_rng(0)
    o = np.stack([obs, obs2])
    for _ in range(min(lengths) + 50):  # past the shorter end, on made-up observations
        acts = batch.act(o)
        for i in range(2):
            assert np.array_equal(acts[i], twins[i].act(o[i]))
        o = o + rng.normal(0, 1e-3, o.shape) * (np.abs(o) > 0)


def test_batch_refuses_members_that_have_acted() -> None:
    comps = [make_compensator("ekf") for _ in range(2)]
    _, obs = _episode(PAPER, 0, "s_curve", comps)
    comps[1].act(obs)
    with pytest.raises(ValueError, match="member 1 has already acted"):
        ExtendedFrictionObserver.batch(comps)


# -- timings (run as a script) ------------------------------------------------------------------

def _us_per_call(fn: Any, n: int) -> float:
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, time.perf_counter() - t0)
    return best / n * 1e6


def _record(env_id: str, traj: str, n_steps: int) -> np.ndarray:
    """Observations of one closed-loop run of ``ekf`` (seed 0), replayed to time acts."""
    comp = make_compensator("ekf")
    env, obs = _episode(env_id, 0, traj, [comp])
    rec = [obs]
    for _ in range(n_steps - 1):
        obs, *_ = env.step(comp.act(obs))
        rec.append(obs)
    return np.stack(rec)


def _time_scalar(cls: type, env_id: str, traj: str, rec: np.ndarray) -> float:
    c = cls()
    _episode(env_id, 0, traj, [c])
    it = iter(rec)
    return _us_per_call(lambda: c.act(next(it)), len(rec) // 3)


def _time_batch(cls: type, env_id: str, traj: str, rec: np.ndarray, n_batch: int) -> float:
    members = [cls() for _ in range(n_batch)]
    for s, m in enumerate(members):
        _episode(env_id, s, traj, [m])
    batch = cls.batch(members)
    it = iter(np.repeat(rec[:, None, :], n_batch, axis=1))
    return _us_per_call(lambda: batch.act(next(it)), len(rec) // 3)


def _timings(n_batch: int = 10, n_steps: int = 2400) -> None:
    """us per act: filterpy vs bank (D = 1, PaperAxis-v0; D = 2, CircleContouring-v0), and
    one batch act of ``n_batch`` episodes vs ``n_batch`` filterpy acts (the default batch,
    row by row). Observations are recorded from one closed-loop run and replayed, so that
    only the compensator is timed (public act: its checks included); best of 3."""
    for env_id, traj in ((PAPER, "s_curve"), (CIRCLE, "circle")):
        rec = _record(env_id, traj, n_steps)
        d = 1 if env_id == PAPER else 2
        us_ref = _time_scalar(FilterpyEKF, env_id, traj, rec)
        us_bank = _time_scalar(ExtendedFrictionObserver, env_id, traj, rec)
        print(f"{env_id} (D={d}) one act: filterpy {us_ref:6.1f} us, bank {us_bank:6.1f} us"
              f"  ({us_ref / us_bank:.1f}x)")
        us_ref_n = _time_batch(FilterpyEKF, env_id, traj, rec, n_batch)
        us_bank_n = _time_batch(ExtendedFrictionObserver, env_id, traj, rec, n_batch)
        print(f"{env_id} (D={d}) N={n_batch}: {n_batch} filterpy acts {us_ref_n:7.1f} us, "
              f"one bank batch act {us_bank_n:6.1f} us  ({us_ref_n / us_bank_n:.1f}x; "
              f"{us_bank_n / n_batch:.1f} us per episode-step)")


if __name__ == "__main__":
    _timings(*(int(a) for a in sys.argv[1:3]))
