"""Run every compensator on every benchmark env x trajectory x seed through the env loop.

Each seed is a machine: its plant is drawn around the env's nominal axis
(:mod:`fricbench.axis.variation`), the same for every compensator, and every compensator that
learns is fitted once per seed on training runs of that seed's plant. ``nominal=True`` runs the
env's nominal, noise-free axis on every seed, with one fit per env (the benchmark as it was
before plants were drawn: its seeds are copies).
"""

from __future__ import annotations

import copy
import inspect
import os
import time
import tomllib
import traceback
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from fricbench.axis import Axis
from fricbench.axis.ballbar import CircleRun, circle_run
from fricbench.axis.variation import draw_plant, nominal_told
from fricbench.bench.metrics import contour_error, score_run
from fricbench.compensators import (
    PRECOMP_PREFIX,
    Compensator,
    compensator_id_kwargs,
    compensator_parameters,
    compensator_registry,
    make_compensator,
)
from fricbench.gym.env import ServoAxisEnv
from fricbench.gym.specs import env_ids as registered_env_ids
from fricbench.gym.specs import get_spec
from fricbench.gym.task import TrajectoryChoice, reference_for
from fricbench.predictors import predictor_registry
from fricbench.registry import did_you_mean
from fricbench.trajectories import Reference, trajectory_registry

__all__ = [
    "BenchConfigError",
    "BenchTask",
    "EpisodeRecord",
    "LostTask",
    "RAY_MAX_RETRIES",
    "bench_env",
    "fit_compensators",
    "plant_axes",
    "plan_benchmark",
    "read_compensator_config",
    "run_cell",
    "run_benchmark",
    "run_episode",
]

MAX_CONFIG_BYTES = 2**20
"""Largest compensator settings file read by :func:`read_compensator_config`, bytes."""

CompKwargs = Mapping[str, Mapping[str, Any]]
"""Constructor keywords per compensator id: ``{"ilc": {"gain": 0.3}}``."""


class BenchConfigError(ValueError):
    """A benchmark argument that cannot run: names the parameter, the offending value and why.

    Raised by :func:`plan_benchmark` (and so by :func:`run_benchmark`) before anything is
    fitted. ``parameter`` is the argument name (``env_ids``, ``comp_ids``, ``trajectories``,
    ``seeds``, ``comp_kwargs``; ``comp_config`` for :func:`read_compensator_config`), ``value``
    the offending item (for ``comp_kwargs``, the compensator id or ``"<id>:<keyword>"``),
    ``problem`` the explanation.
    """

    def __init__(self, parameter: str, value: object, problem: str) -> None:
        super().__init__(f"{parameter}={value!r}: {problem}")
        self.parameter = parameter
        self.value = value
        self.problem = problem


@dataclass(frozen=True)
class BenchTask:
    """One scored episode."""

    env: str
    compensator: str
    trajectory: str
    seed: int


@dataclass
class EpisodeRecord:
    """The outcome of one scored episode (SI units; ``status`` is ``"ok"`` or ``"failed"``;
    ``compensator_kwargs``: the constructor keywords the compensator was made with, beyond its
    registered defaults; ``plant``: ``"seed"`` for the seed's drawn plant, ``"nominal"`` for
    the env's nominal axis; ``trace_*``: with ``keep_trace``, the scored error against time
    and, for a ``circle`` run, what a ballbar reads at the full rate)."""

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
    compensator_kwargs: dict[str, Any] = field(default_factory=dict)
    plant: str = "seed"
    trace_t: np.ndarray | None = field(default=None, repr=False)
    trace_error: np.ndarray | None = field(default=None, repr=False)
    trace_ballbar: CircleRun | None = field(default=None, repr=False)


def plant_axes(env_id: str, seed: int, nominal: bool = False) -> tuple[Axis, Axis]:
    """``(told, plant)`` of benchmark seed ``seed`` on ``env_id``.

    ``told`` is what compensators know (``context.nominal_axis``: the env's nominal axis with the
    sensor noise levels), ``plant`` the machine simulated (:func:`~fricbench.axis.variation.
    draw_plant`). With ``nominal`` both are the env's nominal, noise-free axis.
    """
    axis = get_spec(env_id).axis
    if nominal:
        return axis, axis
    return nominal_told(axis), draw_plant(axis, seed)


def bench_env(env_id: str, compensator: Compensator, seed: int | None = None,
              nominal: bool = False) -> ServoAxisEnv:
    """The env of ``env_id`` in the action mode the compensator produces, on the plant of
    benchmark seed ``seed`` (:func:`plant_axes`; ``None`` or ``nominal``: the nominal axis)."""
    spec = get_spec(env_id)
    task = spec.task
    if compensator.action_mode != task.action:
        scale = (task.offset_scale if compensator.action_mode == "offset" else
                 float(getattr(compensator, "action_scale", task.action_scale)))
        task = replace(task, action=compensator.action_mode, action_scale=scale)
    told, plant = plant_axes(env_id, 0 if seed is None else seed, nominal or seed is None)
    return ServoAxisEnv(axis=told, task=task, plant=plant)


def _env_trajectory(env_id: str, trajectory: str) -> str | TrajectoryChoice:
    """The env's own entry for trajectory id ``trajectory``, with the parameters its spec gives
    it (a twin's ``m_serial`` at its machine's stroke and feed), else the bare id."""
    for choice in get_spec(env_id).task.trajectories:
        if choice.id == trajectory:
            return choice
    return trajectory


class _Episode:
    """One scored episode being run: its env, first observation, reference and traces."""

    def __init__(self, compensator: Compensator, task: BenchTask,
                 reference: Reference | None, nominal: bool) -> None:
        self.env = env = bench_env(task.env, compensator, task.seed, nominal)
        self.obs, _ = env.reset(seed=task.seed,
                                options={"trajectory": reference or _env_trajectory(
                                    task.env, task.trajectory)})
        ref = env.reference
        assert ref is not None
        self.ref = ref
        # rehearsal seeds differ from the scored run's noise seed
        compensator.reset(env.episode_context(), seed=task.seed + 7919)
        self.d, self.k_total = ref.n_axes, ref.n_samples
        self.err = np.zeros((self.d, self.k_total))
        self.effort = np.zeros((self.d, self.k_total))
        self.err[:, 0] = np.atleast_2d(ref.x)[:, 0] - env.true_position
        self.t_act = 0.0

    def run_plan(self, plan: np.ndarray) -> None:
        """The whole episode in one kernel call (the same numbers as the step loop)."""
        self.err[:, 1:] = self.env.run_actions(plan)
        self.effort[:, :-1] = np.asarray(plan, dtype=float) * self.env.task.action_scale

    def score(self, rec: EpisodeRecord, keep_trace: bool) -> None:
        """Fill ``rec`` with the episode's metrics (and its trace with ``keep_trace``)."""
        env, ref, d, k_total, err = self.env, self.ref, self.d, self.k_total, self.err
        x_ref = np.atleast_2d(ref.x)
        x_true = x_ref - err
        v_ref = np.atleast_2d(ref.v)
        sq = (lambda a: a[0] if d == 1 else a)
        m = score_run(ref.t, sq(x_ref), sq(x_true), sq(v_ref), sq(self.effort))
        rec.max_error, rec.rms_error, rec.reversal_peak = m.max_error, m.rms_error, \
            m.reversal_peak
        rec.circular_deviation, rec.reversal_spike = m.circular_deviation, m.reversal_spike
        rec.effort_rms = m.effort_rms
        rec.effort_unit = "N" if env.task.action == "force" else "m"
        rec.n_steps = k_total - 1
        rec.step_time = self.t_act / max(1, k_total - 1)
        if keep_trace:
            stride = max(1, k_total // 4000)
            rec.trace_t = ref.t[::stride].copy()
            # the quantity the tables score: the contour error for two axes (the legend's
            # maximum is over the full-rate run, so the subsampled curve may peak a bit below it)
            traced = contour_error(err, v_ref) if d > 1 else err[0]
            rec.trace_error = traced[::stride].copy()
            if ref.name == "circle" and np.all(np.isfinite(x_true)):
                # the polar picture reads every sample: a glitch lasts a few ms
                rec.trace_ballbar = circle_run(ref, x_true)
        env.close()


def _new_record(task: BenchTask, nominal: bool) -> EpisodeRecord:
    return EpisodeRecord(task.env, task.compensator, task.trajectory, task.seed,
                         plant="nominal" if nominal else "seed")


def _failed(rec: EpisodeRecord, exc: BaseException) -> EpisodeRecord:
    rec.status = "failed"
    last = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    where = f" ({os.path.basename(last.filename)}:{last.lineno})" if last else ""
    rec.reason = f"{type(exc).__name__}: {exc}{where}"[:300]
    return rec


def run_episode(compensator: Compensator, task: BenchTask, keep_trace: bool = False,
                reference: Reference | None = None, nominal: bool = False,
                fast: bool = True) -> EpisodeRecord:
    """Score ``compensator`` on one episode (on the plant of ``task.seed``, or on the nominal
    axis with ``nominal``); any exception becomes a failed record.

    With ``fast``, a compensator whose actions do not depend on the observation
    (:meth:`~fricbench.compensators.Compensator.planned_actions`) runs in one kernel call
    (:meth:`~fricbench.gym.ServoAxisEnv.run_actions`, the same numbers as the step loop);
    ``fast=False`` steps the env one sample at a time for every compensator.
    """
    rec = _new_record(task, nominal)
    try:
        ep = _Episode(compensator, task, reference, nominal)
        env, obs = ep.env, ep.obs
        t0 = time.perf_counter()
        plan = compensator.planned_actions(ep.k_total - 1) if fast else None
        if plan is not None:
            ep.t_act = time.perf_counter() - t0
            ep.run_plan(plan)
        for k in range(ep.k_total - 1 if plan is None else 0):
            t0 = time.perf_counter()
            action = compensator.act(obs)
            ep.t_act += time.perf_counter() - t0
            obs, _, _, truncated, info = env.step(action)
            ep.err[:, k + 1] = info["error_m"]
            ep.effort[:, k] = np.asarray(action, dtype=float) * env.task.action_scale
            if truncated:
                break
        compensator.end_episode()
        ep.score(rec, keep_trace)
    except Exception as exc:  # noqa: BLE001 - a failing compensator is a row, not a crash
        _failed(rec, exc)
    return rec


def run_cell(members: Sequence[Compensator], tasks: Sequence[BenchTask],
             keep_trace: Sequence[bool] | None = None, nominal: bool = False,
             ) -> list[EpisodeRecord]:
    """Score the episodes of one cell (one env, compensator and trajectory; a seed each),
    ``members[i]`` on ``tasks[i]``: the same records as :func:`run_episode` on each, faster.

    Compensators with planned actions run each in one kernel call. The others are stepped
    together: their envs in lockstep (:class:`~fricbench.gym.lockstep.LockstepEnvs`, one kernel
    call per sample for every seed) and their actions from one
    :meth:`~fricbench.compensators.Compensator.batch` (one call per sample), both exactly the
    numbers of each episode run alone. Should the lockstep fail (a diverging plant, a
    compensator raising, references of different lengths), its episodes are rerun one by one,
    so each failure is the record of its own seed.
    """
    from fricbench.gym.lockstep import LockstepEnvs

    if len(members) != len(tasks):
        raise ValueError(f"members: {len(members)} compensators for {len(tasks)} tasks")
    keep = list(keep_trace) if keep_trace is not None else [False] * len(tasks)
    # one object given for several seeds (a nominal fit): each episode needs its own state
    members = [copy.deepcopy(m) if any(m is o for o in members[:i]) else m
               for i, m in enumerate(members)]
    records = [_new_record(t, nominal) for t in tasks]
    stepped: list[int] = []
    episodes: dict[int, _Episode] = {}
    for i, (comp, task) in enumerate(zip(members, tasks, strict=True)):
        try:
            ep = _Episode(comp, task, None, nominal)
            t0 = time.perf_counter()
            plan = comp.planned_actions(ep.k_total - 1)
            if plan is None:
                episodes[i] = ep
                stepped.append(i)
                continue
            ep.t_act = time.perf_counter() - t0
            ep.run_plan(plan)
            comp.end_episode()
            ep.score(records[i], keep[i])
        except Exception as exc:  # noqa: BLE001 - a failing compensator is a row, not a crash
            _failed(records[i], exc)
    if len(stepped) == 1:
        i = stepped[0]
        records[i] = run_episode(members[i], tasks[i], keep_trace=keep[i], nominal=nominal)
    elif stepped:
        try:
            eps = [episodes[i] for i in stepped]
            lock = LockstepEnvs([ep.env for ep in eps])
            batch = type(members[stepped[0]]).batch([members[i] for i in stepped])
            obs = np.stack([ep.obs for ep in eps])
            t_act = 0.0
            errs = np.stack([ep.err for ep in eps])            # (N, D, K)
            efforts = np.stack([ep.effort for ep in eps])
            scale = np.array([ep.env.task.action_scale for ep in eps])[:, None]
            for k in range(lock.n_samples - 1):
                t0 = time.perf_counter()
                actions = batch.act(obs)
                t_act += time.perf_counter() - t0
                obs, errs[:, :, k + 1] = lock.step(actions)
                efforts[:, :, k] = actions.astype(float) * scale
            lock.close()
            batch.end_episode()
            for j, (i, ep) in enumerate(zip(stepped, eps, strict=True)):
                ep.err, ep.effort = errs[j], efforts[j]
                # the batch's act time shared by its rows: the cost of one episode's step
                ep.t_act = t_act / len(eps)
                ep.score(records[i], keep[i])
        except Exception:  # noqa: BLE001 - rerun alone: each failure is its own seed's record
            for i in stepped:
                records[i] = run_episode(members[i], tasks[i], keep_trace=keep[i],
                                         nominal=nominal)
    return records


def _fit_one(comp_id: str, fit_env: str, seed: int,
             kwargs: Mapping[str, Any] | None = None,
             plant: Axis | None = None) -> tuple[Compensator | None, str]:
    try:
        comp = make_compensator(comp_id, **(kwargs or {}))
        # a fit without the axis keyword (written before plants were drawn) learns on the
        # nominal axis: a handicap, never an advantage
        if plant is not None and "axis" in inspect.signature(comp.fit).parameters:
            comp.fit(fit_env, seed=seed, axis=plant)
        else:
            comp.fit(fit_env, seed=seed)
        return comp, ""
    except Exception as exc:  # noqa: BLE001 - recorded on every row of this compensator
        return None, f"fit failed: {type(exc).__name__}: {exc}"[:300]


# map_fn(fn, arglist) yields (index into arglist, fn(*arglist[index])) as each call finishes
MapFn = Callable[[Callable[..., Any], list[tuple[Any, ...]]], Iterable[tuple[int, Any]]]


FIT_SEED_STRIDE = 100
"""The fit of plant seed ``s`` uses ``fit_seed + FIT_SEED_STRIDE * s`` (training references and
noise), apart from the episode seeds and from the fits of the other seeds."""


def _timed(fn: Callable[..., Any], *args: Any) -> tuple[Any, float]:
    """``(fn(*args), CPU seconds it took)``: the work of one mapped call, timed in the process
    that runs it (CPU time: what other programs on the machine take is not counted)."""
    t0 = time.process_time()
    out = fn(*args)
    return out, time.process_time() - t0


def _timed_fit(*args: Any) -> tuple[tuple[Compensator | None, str], float]:
    return _timed(_fit_one, *args)


def _timed_cell(*args: Any) -> tuple[list[EpisodeRecord], float]:
    return _timed(_run_cell_task, *args)


def fit_compensators(comp_ids: Sequence[str], env_ids: Sequence[str], seed: int,
                     map_fn: MapFn, comp_kwargs: CompKwargs | None = None,
                     plant_seeds: Sequence[int] | None = None,
                     work: dict[str, float] | None = None,
                     ) -> dict[tuple[str, str, int | None], tuple[Compensator | None, str]]:
    """Fit each compensator once per training env (``fit_on`` of each benchmark env) and per
    plant seed.

    ``map_fn(fn, arglist)`` yields ``(index, fn(*arglist[index]))`` in any order;
    ``comp_kwargs`` gives constructor keywords per compensator id. With ``plant_seeds``, each
    seed ``s`` gets its own fit on the plant :func:`plant_axes` draws for it, with the fit seed
    ``seed + FIT_SEED_STRIDE * s``, keyed ``(compensator, fit env, s)``; without, one fit on
    the nominal axis with ``seed``, keyed ``(compensator, fit env, None)``. ``work``, when
    given, gets the CPU seconds each fit took added to its training env's entry.
    """
    pairs = sorted({(c, get_spec(e).fit_on) for c in comp_ids for e in env_ids})
    kwargs = comp_kwargs or {}
    keys: list[tuple[str, str, int | None]] = []
    args: list[tuple[Any, ...]] = []
    for s in (sorted(set(plant_seeds)) if plant_seeds is not None else [None]):
        for c, f in pairs:
            keys.append((c, f, s))
            if s is None:
                args.append((c, f, seed, dict(kwargs.get(c, {}))))
            else:
                args.append((c, f, seed + FIT_SEED_STRIDE * s, dict(kwargs.get(c, {})),
                             plant_axes(f, s)[1]))
    results: dict[int, Any] = {}
    for i, res in map_fn(_timed_fit, args):
        if isinstance(res, LostTask):
            results[i] = (None, f"fit failed: {res.reason}")
            continue
        results[i], seconds = res
        if work is not None:
            work[keys[i][1]] = work.get(keys[i][1], 0.0) + seconds
    return {key: results[i] for i, key in enumerate(keys)}


def _indexed(i: int, fn: Callable[..., Any], args: tuple[Any, ...]) -> tuple[int, Any]:
    return i, fn(*args)


def _joblib_map(n_jobs: int, progress: Callable[[Any], None] | None) -> MapFn:
    from joblib import Parallel, delayed

    def map_fn(fn: Callable[..., Any],
               arglist: list[tuple[Any, ...]]) -> Iterator[tuple[int, Any]]:
        par = Parallel(n_jobs=n_jobs, return_as="generator_unordered")
        for res in par(delayed(_indexed)(i, fn, args) for i, args in enumerate(arglist)):
            if progress:
                progress(res[1])
            yield res

    return map_fn


RAY_MAX_RETRIES = 2
"""Times Ray reruns a task whose worker died (killed, out of memory, node lost) before the
runner gives it up as :class:`LostTask`. A rerun gives the same numbers: every random draw of a
fit or a cell comes from its seeds."""


@dataclass(frozen=True)
class LostTask:
    """What a backend yields for a mapped call it could not complete (its worker died more
    than :data:`RAY_MAX_RETRIES` times): ``reason`` says why. The runner turns it into a failed
    fit or failed records of the cell's episodes, so the other results are kept."""

    reason: str


def _ray_map(address: str | None, progress: Callable[[Any], None] | None) -> MapFn:
    import ray
    from ray.exceptions import RayError

    if not ray.is_initialized():
        ray.init(address=address, include_dashboard=False, log_to_driver=False,
                 ignore_reinit_error=True)

    def map_fn(fn: Callable[..., Any],
               arglist: list[tuple[Any, ...]]) -> Iterator[tuple[int, Any]]:
        # a task whose worker dies is rerun by Ray (retry_exceptions stays off: the mapped
        # functions turn their own exceptions into results)
        remote = ray.remote(max_retries=RAY_MAX_RETRIES)(fn)
        futures = [remote.remote(*args) for args in arglist]
        order = {f: i for i, f in enumerate(futures)}
        pending = list(futures)
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for f in done:
                    try:
                        res = ray.get(f)
                    except RayError as exc:  # its worker died on every try: the others go on
                        first = (str(exc).strip().splitlines() or [""])[0]
                        res = LostTask(f"{type(exc).__name__} after {RAY_MAX_RETRIES} "
                                       f"retries: {first}"[:300])
                    if progress:
                        progress(res)
                    yield order[f], res
        finally:
            for f in pending:  # interrupted (or the consumer stopped): drop what is left
                ray.cancel(f)

    return map_fn


def _run_cell_task(fits: list[tuple[Compensator | None, str]], tasks: list[BenchTask],
                   keep_trace: list[bool], nominal: bool = False) -> list[EpisodeRecord]:
    """The runs of one cell: :func:`run_cell` on the seeds whose fit succeeded, a failed record
    (the fit's reason) for the others."""
    records: list[EpisodeRecord | None] = [None] * len(tasks)
    ok = [i for i, (comp, _) in enumerate(fits) if comp is not None]
    for i, (comp, reason) in enumerate(fits):
        if comp is None:
            records[i] = EpisodeRecord(tasks[i].env, tasks[i].compensator, tasks[i].trajectory,
                                       tasks[i].seed, status="failed", reason=reason,
                                       plant="nominal" if nominal else "seed")
    done = run_cell([fits[i][0] for i in ok], [tasks[i] for i in ok],  # type: ignore[misc]
                    [keep_trace[i] for i in ok], nominal) if ok else []
    for i, rec in zip(ok, done, strict=True):
        records[i] = rec
    return [r for r in records if r is not None]


def _progress_weight(result: Any) -> int:
    """Progress ticks of one mapped result: a cell's list of records (timed or not) counts
    each run."""
    if isinstance(result, tuple) and len(result) == 2 and isinstance(result[0], list):
        result = result[0]
    return len(result) if isinstance(result, list) else 1


def _n_axes(env_id: str, trajectory: str | TrajectoryChoice) -> int:
    ts = get_spec(env_id).axis.controller.ts
    return reference_for(TrajectoryChoice.parse(trajectory), ts, np.random.default_rng(0)).n_axes


def read_compensator_config(path: str | Path) -> dict[str, dict[str, Any]]:
    """Constructor keywords per compensator from a TOML file: one table per compensator id.

    ::

        [ilc]
        gain = 0.3
        iterations = 20

        ["precomp:tf"]          # ids with a colon are quoted
        advance = 2

    The keywords themselves are checked by :func:`plan_benchmark`.

    Raises
    ------
    BenchConfigError
        ``parameter="comp_config"``, ``value`` the path: a file that cannot be read, is larger
        than :data:`MAX_CONFIG_BYTES`, is not UTF-8 TOML, or holds a value outside a table.
    """
    try:
        with Path(path).open("rb") as fh:
            raw = fh.read(MAX_CONFIG_BYTES + 1)
    except OSError as exc:
        raise BenchConfigError("comp_config", str(path),
                               f"cannot read ({exc.strerror or exc})") from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise BenchConfigError("comp_config", str(path),
                               f"larger than {MAX_CONFIG_BYTES} bytes (MAX_CONFIG_BYTES)")
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise BenchConfigError("comp_config", str(path),
                               f"not UTF-8 text (byte {exc.start})") from None
    except (tomllib.TOMLDecodeError, RecursionError) as exc:
        raise BenchConfigError("comp_config", str(path), f"invalid TOML: {exc}") from None
    for key, value in data.items():
        if not isinstance(value, dict):
            raise BenchConfigError("comp_config", str(path),
                                   f"{key} = {value!r}: expected a table of one compensator's "
                                   f"settings, [{key}] followed by keyword = value lines")
    return data


def _check_comp_kwargs(comp_kwargs: CompKwargs, comp_ids: Sequence[str],
                       known: Sequence[str], fit_envs: Sequence[str] = ()) -> None:
    """Each id known and run, each keyword one its constructor takes, the compensator built
    with them (its own checks), and what its fit will read checked on each of ``fit_envs``
    (:meth:`~fricbench.compensators.Compensator.check_setup`: a policy file loaded)."""
    if not isinstance(comp_kwargs, Mapping):
        raise BenchConfigError("comp_kwargs", comp_kwargs,
                               "expected a mapping of compensator id to {keyword: value}")
    for cid, kwargs in comp_kwargs.items():
        if cid not in known:
            raise BenchConfigError("comp_kwargs", cid, f"unknown compensator id"
                                                       f"{did_you_mean(cid, known)} (expected "
                                                       f"one of {', '.join(known)})")
        if cid not in comp_ids:
            raise BenchConfigError("comp_kwargs", cid, "settings for a compensator that is not "
                                                       f"run (running {', '.join(comp_ids)}); "
                                                       "run it too, or drop its settings")
        if not isinstance(kwargs, Mapping):
            raise BenchConfigError("comp_kwargs", cid, f"{kwargs!r}: expected a mapping of "
                                                       "keyword to value")
        accepted = compensator_parameters(cid)
        fixed = compensator_id_kwargs(cid)
        for key in kwargs:
            if key in fixed:
                raise BenchConfigError("comp_kwargs", f"{cid}:{key}",
                                       f"the id {cid!r} names {key}={fixed[key]!r}; it cannot "
                                       "change under this id (choose the compensator id "
                                       "registered with the one you want)")
            if accepted is not None and key not in accepted:
                takes = (f"accepted: {', '.join(accepted)}" if accepted
                         else "it takes no keywords")
                raise BenchConfigError("comp_kwargs", f"{cid}:{key}",
                                       f"not a keyword of compensator {cid!r}"
                                       f"{did_you_mean(key, accepted)}; {takes}")
        try:
            comp = make_compensator(cid, **kwargs)
        except (TypeError, ValueError) as exc:
            raise BenchConfigError("comp_kwargs", cid, str(exc)) from None
        if not kwargs:
            continue
        for env_id in fit_envs:
            try:
                comp.check_setup(env_id)
            except Exception as exc:  # noqa: BLE001 - a plug-in's check may raise anything
                raise BenchConfigError("comp_kwargs", cid,
                                       f"{exc} (checked on {env_id})") from None


def plan_benchmark(env_ids: Sequence[str], comp_ids: Sequence[str], seeds: Sequence[int],
                   trajectories: Sequence[str] | None = None,
                   comp_kwargs: CompKwargs | None = None) -> list[BenchTask]:
    """Check every id, seed and compensator setting, then list the episodes
    :func:`run_benchmark` scores.

    Nothing is fitted or run: a typo fails here in a fraction of a second, not after the fits.
    Each compensator with settings in ``comp_kwargs`` is built once with them, so that its
    constructor checks the values, and checks on each training env what its fit will read
    (:meth:`~fricbench.compensators.Compensator.check_setup`: a policy file named by a
    setting is loaded here, so that a missing or corrupt one is a bad option).

    Raises
    ------
    BenchConfigError
        Naming the parameter and the value: an unknown env, compensator or trajectory id (with
        near matches), a trajectory whose number of axes an env does not drive, a seed that is
        not an integer >= 0, an empty list, or an id or seed given twice; in ``comp_kwargs``,
        settings of an unknown compensator or one not run, a keyword its constructor does not
        take (with near matches and the accepted keywords), a value its constructor refuses
        (its message), or a file it names that its ``check_setup`` refuses (missing, corrupt,
        for another env).
    """
    known_envs = registered_env_ids()
    # precomp:<predictor id> names a pre-compensation with any registered predictor
    known_comps = compensator_registry.ids() + [PRECOMP_PREFIX + p
                                                for p in predictor_registry.ids()]
    known_trajs = trajectory_registry.ids()
    for name, values in (("env_ids", env_ids), ("comp_ids", comp_ids), ("seeds", seeds),
                         ("trajectories", trajectories)):
        if values is not None and len(values) == 0:
            raise BenchConfigError(name, list(values), "expected at least one")
    for name, values, known, kind in (("env_ids", env_ids, known_envs, "env"),
                                      ("comp_ids", comp_ids, known_comps, "compensator"),
                                      ("trajectories", trajectories or (), known_trajs,
                                       "trajectory")):
        for v in values:
            if v not in known:
                raise BenchConfigError(name, v, f"unknown {kind} id{did_you_mean(v, known)} "
                                                f"(expected one of {', '.join(known)})")
    for seed in seeds:
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise BenchConfigError("seeds", seed, "expected an integer >= 0")
    given: tuple[tuple[str, Sequence[object]], ...] = (
        ("env_ids", env_ids), ("comp_ids", comp_ids), ("seeds", seeds),
        ("trajectories", trajectories or ()))
    for name, items in given:
        seen: set[object] = set()
        for item in items:
            if item in seen:
                raise BenchConfigError(name, item, "given twice; expected each once (a repeat "
                                                   "would score the same runs twice)")
            seen.add(item)
    if comp_kwargs is not None:
        _check_comp_kwargs(comp_kwargs, comp_ids, known_comps,
                           sorted({get_spec(e).fit_on for e in env_ids}))
    tasks = []
    for env_id in env_ids:
        spec = get_spec(env_id)
        trajs = list(trajectories) if trajectories else [t.id for t in spec.task.trajectories]
        if trajectories:
            d_env = _n_axes(env_id, spec.task.trajectories[0])
            for traj in trajs:
                d = _n_axes(env_id, traj)
                if d != d_env:
                    raise BenchConfigError("trajectories", traj,
                                           f"a {d}-axis trajectory; {env_id} drives {d_env} "
                                           f"axis{'' if d_env == 1 else 'es'}")
        for comp_id in comp_ids:
            for traj in trajs:
                for seed in seeds:
                    tasks.append(BenchTask(env_id, comp_id, traj, int(seed)))
    return tasks


def run_benchmark(env_ids: Sequence[str], comp_ids: Sequence[str],
                  seeds: Sequence[int], trajectories: Sequence[str] | None = None,
                  backend: str = "joblib", n_jobs: int = 2, address: str | None = None,
                  fit_seed: int = 1000, progress: bool = True,
                  comp_kwargs: CompKwargs | None = None,
                  nominal: bool = False,
                  work: dict[str, float] | None = None) -> Iterator[EpisodeRecord]:
    """Fit, then run every (env, compensator, trajectory, seed); yields records as they finish.

    Every argument is checked by :func:`plan_benchmark` before anything is fitted. Records come
    in completion order, so a consumer stopped early (Ctrl-C) holds every finished run.

    Parameters
    ----------
    env_ids : sequence of str
        Registered env ids; each is scored on its own trajectory set (or ``trajectories``).
    comp_ids : sequence of str
        Registered compensator ids.
    seeds : sequence of int
        Seeds, integers >= 0: each draws the plant (:mod:`fricbench.axis.variation`), the
        episode's measurement noise and the rehearsal seeds, and has its own fits.
    trajectories : sequence of str, optional
        Registered trajectory ids replacing each env's own set.
    backend : {"joblib", "ray"}
        ``joblib`` fans out over local cores; ``ray`` runs the same tasks on a Ray cluster
        (``address`` of a running cluster, or a local instance when None). On Ray, a fit or a
        cell whose worker dies is rerun (:data:`RAY_MAX_RETRIES` times, the same numbers),
        then recorded as failed (its reason says the worker was lost); the other runs go on.
    fit_seed : int
        Seed of the fits (training data differ from every evaluation episode): seed ``s`` fits
        with ``fit_seed + FIT_SEED_STRIDE * s`` (with ``nominal``: every fit with ``fit_seed``).
    comp_kwargs : mapping, optional
        Constructor keywords per compensator id (``{"ilc": {"gain": 0.3}}``), over the
        registered defaults; each record carries those of its compensator.
    nominal : bool
        Run the env's nominal, noise-free axis on every seed, each compensator fitted once per
        training env (as ``fricbench reproduce`` and the docs' figures; the seeds are copies).
    work : dict, optional
        Filled as the run goes with the CPU seconds of work per env id, summed over the
        processes (each fit counted under its training env, each cell under its env): where the
        time of a run goes, whatever the number of jobs and the machine's other load.

    Raises
    ------
    BenchConfigError
        An unknown id or a bad seed (see :func:`plan_benchmark`), before any fitting.
    """
    from tqdm import tqdm

    if backend not in ("joblib", "ray"):
        raise ValueError(f"backend={backend!r}: expected 'joblib' or 'ray'")
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or (n_jobs < 1 and n_jobs != -1):
        raise ValueError(f"n_jobs={n_jobs!r}: expected a positive number of processes, or -1 "
                         "for one per core")
    tasks = plan_benchmark(env_ids, comp_ids, seeds, trajectories, comp_kwargs)
    settings = {c: dict(kw) for c, kw in (comp_kwargs or {}).items() if kw}
    n_fits = len({(c, get_spec(e).fit_on) for c in comp_ids for e in env_ids}) * (
        1 if nominal else len(set(seeds)))
    # two bars: the fits, then the runs (the bench bar counts the runs the summary counts)
    bars = [tqdm(total=n_fits, desc="fit", unit="fit", disable=not progress)]
    try:
        def tick(result: Any) -> None:
            bars[-1].update(_progress_weight(result))

        map_fn = _joblib_map(n_jobs, tick) if backend == "joblib" else _ray_map(address, tick)
        fitted = fit_compensators(comp_ids, env_ids, fit_seed, map_fn, settings,
                                  None if nominal else seeds, work)
        bars[0].close()
        bars.append(tqdm(total=len(tasks), desc="bench", unit="run", disable=not progress))
        first_seed = min(seeds)
        # one job per cell (env, compensator, trajectory): its seeds stepped together
        cells: dict[tuple[str, str, str], list[BenchTask]] = {}
        for t in tasks:
            cells.setdefault((t.env, t.compensator, t.trajectory), []).append(t)
        args = [([fitted[(t.compensator, get_spec(t.env).fit_on, None if nominal else t.seed)]
                  for t in cell], cell, [t.seed == first_seed for t in cell], nominal)
                for cell in cells.values()]
        for i, res in map_fn(_timed_cell, args):
            if isinstance(res, LostTask):  # the cell's worker died on every try
                recs = [replace(_new_record(t, nominal), status="failed",
                                reason=f"cell lost: {res.reason}"[:300]) for t in args[i][1]]
            else:
                recs, seconds = res
                if work is not None:
                    env = args[i][1][0].env
                    work[env] = work.get(env, 0.0) + seconds
            for rec in recs:
                rec.compensator_kwargs = dict(settings.get(rec.compensator, {}))
                yield rec
    finally:
        for bar in bars:
            bar.close()
