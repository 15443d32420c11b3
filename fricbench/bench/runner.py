"""Run every compensator on every benchmark env x trajectory x seed through the env loop."""

from __future__ import annotations

import os
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from fricbench.axis import SimulationResult, simulate
from fricbench.bench.metrics import score_run
from fricbench.compensators import Compensator, EpisodeContext, make_compensator
from fricbench.gym.env import ServoAxisEnv
from fricbench.gym.specs import get_spec
from fricbench.trajectories import Reference

__all__ = [
    "BenchTask",
    "EpisodeRecord",
    "bench_env",
    "fit_compensators",
    "run_benchmark",
    "run_episode",
]


@dataclass(frozen=True)
class BenchTask:
    """One scored episode."""

    env: str
    compensator: str
    trajectory: str
    seed: int


@dataclass
class EpisodeRecord:
    """The outcome of one scored episode (SI units; ``status`` is ``"ok"`` or ``"failed"``)."""

    env: str
    compensator: str
    trajectory: str
    seed: int
    status: str = "ok"
    reason: str = ""
    max_error: float = float("nan")
    rms_error: float = float("nan")
    reversal_peak: float = float("nan")
    circular_deviation: float = float("nan")
    reversal_spike: float = float("nan")
    effort_rms: float = float("nan")
    effort_unit: str = ""
    step_time: float = float("nan")
    n_steps: int = 0
    trace_t: np.ndarray | None = field(default=None, repr=False)
    trace_error: np.ndarray | None = field(default=None, repr=False)


def bench_env(env_id: str, compensator: Compensator) -> ServoAxisEnv:
    """The env of ``env_id`` in the action mode the compensator produces."""
    spec = get_spec(env_id)
    task = spec.task
    if compensator.action_mode != task.action:
        scale = float(getattr(compensator, "action_scale", 1e-4 if
                              compensator.action_mode == "offset" else task.action_scale))
        task = replace(task, action=compensator.action_mode, action_scale=scale)
    return ServoAxisEnv(axis=spec.axis, task=task)


def _rehearser(env: ServoAxisEnv) -> Callable[[np.ndarray, int], SimulationResult]:
    axis, ref, mode = env.current_axis, env.reference, env.task.action
    if ref is None:
        raise RuntimeError("reset the env before building its rehearser")

    def rehearse(u: np.ndarray, seed: int) -> SimulationResult:
        """Run the episode's reference on the episode's axis with feedforward ``u``."""
        if mode == "force":
            return simulate(axis, ref, seed=seed, u_force=u)
        return simulate(axis, ref, seed=seed, u_offset=u)

    return rehearse


def run_episode(compensator: Compensator, task: BenchTask, keep_trace: bool = False,
                reference: Reference | None = None) -> EpisodeRecord:
    """Score ``compensator`` on one episode; any exception becomes a failed record."""
    rec = EpisodeRecord(task.env, task.compensator, task.trajectory, task.seed)
    try:
        env = bench_env(task.env, compensator)
        obs, _ = env.reset(seed=task.seed,
                           options={"trajectory": reference or task.trajectory})
        ref = env.reference
        assert ref is not None
        ctx = EpisodeContext(reference=ref, nominal_axis=env.axis, task=env.task,
                             rehearse=_rehearser(env))
        # rehearsal seeds differ from the scored run's noise seed
        compensator.reset(ctx, seed=task.seed + 7919)
        d, k_total = ref.n_axes, ref.n_samples
        err = np.zeros((d, k_total))
        effort = np.zeros((d, k_total))
        err[:, 0] = np.atleast_2d(ref.x)[:, 0] - env._batch.true_position
        t_act = 0.0
        for k in range(k_total - 1):
            t0 = time.perf_counter()
            action = compensator.act(obs)
            t_act += time.perf_counter() - t0
            obs, _, _, truncated, info = env.step(action)
            err[:, k + 1] = info["error_m"]
            effort[:, k] = np.asarray(action, dtype=float) * env.task.action_scale
            if truncated:
                break
        compensator.end_episode()
        x_ref = np.atleast_2d(ref.x)
        x_true = x_ref - err
        v_ref = np.atleast_2d(ref.v)
        sq = (lambda a: a[0] if d == 1 else a)
        m = score_run(ref.t, sq(x_ref), sq(x_true), sq(v_ref), sq(effort))
        rec.max_error, rec.rms_error, rec.reversal_peak = m.max_error, m.rms_error, \
            m.reversal_peak
        rec.circular_deviation, rec.reversal_spike = m.circular_deviation, m.reversal_spike
        rec.effort_rms = m.effort_rms
        rec.effort_unit = "N" if env.task.action == "force" else "m"
        rec.n_steps = k_total - 1
        rec.step_time = t_act / max(1, k_total - 1)
        if keep_trace:
            stride = max(1, k_total // 4000)
            rec.trace_t = ref.t[::stride].copy()
            rec.trace_error = (err[:, ::stride] if d > 1 else err[0, ::stride]).copy()
        env.close()
    except Exception as exc:  # noqa: BLE001 - a failing compensator is a row, not a crash
        rec.status = "failed"
        last = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
        where = f" ({os.path.basename(last.filename)}:{last.lineno})" if last else ""
        rec.reason = f"{type(exc).__name__}: {exc}{where}"[:300]
    return rec


def _fit_one(comp_id: str, fit_env: str, seed: int) -> tuple[Compensator | None, str]:
    try:
        comp = make_compensator(comp_id)
        comp.fit(fit_env, seed=seed)
        return comp, ""
    except Exception as exc:  # noqa: BLE001 - recorded on every row of this compensator
        return None, f"fit failed: {type(exc).__name__}: {exc}"[:300]


def fit_compensators(comp_ids: Sequence[str], env_ids: Sequence[str], seed: int,
                     map_fn: Callable[..., Iterable[Any]]) -> dict[tuple[str, str], tuple[
                         Compensator | None, str]]:
    """Fit each compensator once per training env (``fit_on`` of each benchmark env)."""
    pairs = sorted({(c, get_spec(e).fit_on) for c in comp_ids for e in env_ids})
    results = map_fn(_fit_one, [(c, f, seed) for c, f in pairs])
    return dict(zip(pairs, results, strict=True))


def _joblib_map(n_jobs: int, progress: Callable[[], None] | None) -> Callable[..., list[Any]]:
    from joblib import Parallel, delayed

    def map_fn(fn: Callable[..., Any], arglist: list[tuple[Any, ...]]) -> list[Any]:
        par = Parallel(n_jobs=n_jobs, return_as="generator")
        out = []
        for res in par(delayed(fn)(*args) for args in arglist):
            out.append(res)
            if progress:
                progress()
        return out

    return map_fn


def _ray_map(address: str | None, progress: Callable[[], None] | None) -> Callable[..., list[Any]]:
    import ray

    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False,
                 ignore_reinit_error=True)

    def map_fn(fn: Callable[..., Any], arglist: list[tuple[Any, ...]]) -> list[Any]:
        remote = ray.remote(fn)
        futures = [remote.remote(*args) for args in arglist]
        order = {f: i for i, f in enumerate(futures)}
        out: list[Any] = [None] * len(futures)
        pending = list(futures)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for f in done:
                out[order[f]] = ray.get(f)
                if progress:
                    progress()
        return out

    return map_fn


def _run_task(comp: Compensator | None, fit_reason: str, task: BenchTask,
              keep_trace: bool) -> EpisodeRecord:
    if comp is None:
        return EpisodeRecord(task.env, task.compensator, task.trajectory, task.seed,
                             status="failed", reason=fit_reason)
    return run_episode(comp, task, keep_trace=keep_trace)


def run_benchmark(env_ids: Sequence[str], comp_ids: Sequence[str],
                  seeds: Sequence[int], trajectories: Sequence[str] | None = None,
                  backend: str = "joblib", n_jobs: int = 2, address: str | None = None,
                  fit_seed: int = 1000, progress: bool = True) -> Iterator[EpisodeRecord]:
    """Fit, then run every (env, compensator, trajectory, seed); yields records.

    Parameters
    ----------
    env_ids : sequence of str
        Registered env ids; each is scored on its own trajectory set (or ``trajectories``).
    comp_ids : sequence of str
        Registered compensator ids.
    seeds : sequence of int
        Episode seeds (measurement noise and rehearsal seeds).
    backend : {"joblib", "ray"}
        ``joblib`` fans out over local cores; ``ray`` runs the same tasks on a Ray cluster
        (``address`` of a running cluster, or a local instance when None).
    fit_seed : int
        Seed of every ``fit`` (training data differ from every evaluation episode).
    """
    from tqdm import tqdm

    tasks = []
    for env_id in env_ids:
        spec = get_spec(env_id)
        trajs = trajectories or [t.id for t in spec.task.trajectories]
        for comp_id in comp_ids:
            for traj in trajs:
                for seed in seeds:
                    tasks.append(BenchTask(env_id, comp_id, traj, int(seed)))
    n_fits = len({(c, get_spec(e).fit_on) for c in comp_ids for e in env_ids})
    bar = tqdm(total=len(tasks) + n_fits, desc="bench", unit="run", disable=not progress)
    tick = bar.update
    if backend == "joblib":
        map_fn = _joblib_map(n_jobs, tick)
    elif backend == "ray":
        map_fn = _ray_map(address, tick)
    else:
        raise ValueError(f"backend={backend!r}: expected 'joblib' or 'ray'")
    fitted = fit_compensators(comp_ids, env_ids, fit_seed, map_fn)
    first_seed = min(seeds)
    args = [(*fitted[(t.compensator, get_spec(t.env).fit_on)], t, t.seed == first_seed)
            for t in tasks]
    yield from map_fn(_run_task, args)
    bar.close()
