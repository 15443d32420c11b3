"""Grey-box models of a run and their two fits.

* :class:`GreyBox` is one model: a linear controller, a mass with damping and the force and
  output effects chosen so far (plant row of :mod:`fricbench.sysid.diagnose.closed_loop`).
* :class:`InverseDynamics` fits the plant from an effort (measured, or computed by the
  identified controller from the measured position): ``u = M a + B v + F_eff(x, v)`` by least
  squares on filtered, decimated columns (IDIM-LS), with the nonlinear parameters of an effect
  (Stribeck velocity, spatial periods) searched by variable projection.
* :class:`PositionFit` fits any subset of controller, plant and effect parameters to the measured
  position by output error: the model runs free on the reference and the simulated position is
  compared with the measured one (bounded trust-region least squares, Jacobian by batched finite
  differences). :class:`JointPositionFit` does the same on several runs of one axis at once
  (the ``greybox`` predictor's fit).
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from functools import partial
from typing import TypeVar, cast

import numpy as np
from scipy import optimize, signal

from fricbench._blas import one_blas_thread
from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.controllers import (
    ArxController,
    CascadeController,
    LoopInputs,
    PositionalLaw,
)
from fricbench.sysid.diagnose.effects import get_effect
from fricbench.sysid.diagnose.leastsq import bounded_least_squares, matvec, solve_ls, sumsq
from fricbench.sysid.diagnose.parameters import Bounds, Param
from fricbench.sysid.diagnose.prepared import Prepared
from fricbench.sysid.diagnose.settings import defaults
from fricbench.sysid.diagnose.signals import (
    decimate_columns,
    fold_blocks,
)

__all__ = ["GreyBox", "simulate_position", "simulate_models", "simulate_inputs", "Param",
           "position_params", "PositionFit", "JointPositionFit", "InverseDynamics",
           "cascade_effort", "Bounds", "prediction_floor", "NoStartError", "run_concurrently",
           "race_fits"]

_T = TypeVar("_T")
_LOCK = threading.Lock()


class NoStartError(ValueError):
    """An effect's nonlinear parameter has no start on this run (it cannot be fitted)."""


_DIVERGED = 1.0e3  # residual (in noise-floor units) given to samples of a diverged simulation


@dataclass
class GreyBox:
    """One grey-box closed-loop model.

    Attributes
    ----------
    controller : CascadeController or ArxController
    plant : ndarray, shape (N_PLANT,)
        Mass, damping and effect parameters.
    effects : tuple of str
        Effects in the model, in the order they were added.
    """

    controller: CascadeController | ArxController
    plant: np.ndarray
    effects: tuple[str, ...] = ()

    def copy(self, **changes: object) -> GreyBox:
        """A deep copy with some fields changed."""
        out = replace(self, **changes)  # type: ignore[arg-type]
        out.plant = np.array(out.plant, dtype=float)
        return out

    def without(self, effect: str) -> GreyBox:
        """A copy with ``effect`` switched off (its parameters zeroed)."""
        p = get_effect(effect).zeroed(self.plant, self.effects)
        return self.copy(plant=p, effects=tuple(e for e in self.effects if e != effect))


def simulate_models(models: Sequence[GreyBox], prep: Prepared, w: np.ndarray | None = None,
                    noise: np.ndarray | None = None, quant: float = 0.0,
                    other: np.ndarray | None = None, *, effort: bool = True,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Free-run position of several models on ``prep``'s reference, in parallel.

    ``noise`` (m) and ``quant`` (m) add sensor noise and quantisation (for the noise floor);
    ``other`` (N, K), when given, receives the other encoder's position (the load's when the
    model logs the motor). Returns ``(y, u, status)`` with shapes (N, K), (N, K), (N,).
    With ``effort=False`` the caller does not need ``u`` (it may come back NaN): a run is
    then kept without its effort, and more runs fit the cache of :class:`_FreeRunCache`.
    """
    return simulate_inputs(models, prep.inputs, prep.n_sub, w, noise, quant, other,
                           effort=effort)


def simulate_inputs(models: Sequence[GreyBox], inp: LoopInputs, n_sub: int = 2,
                    w: np.ndarray | None = None, noise: np.ndarray | None = None,
                    quant: float = 0.0, other: np.ndarray | None = None, *,
                    effort: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`simulate_models` on bare loop inputs (a reference without a measured run).

    With ``inp.n_loop`` > 1 the loop runs on :attr:`LoopInputs.fine` (``w`` and ``noise``
    held over each logged period) and the outputs are its values at the logged samples.
    """
    if inp.n_loop > 1:
        k = inp.n_loop
        f = inp.fine
        n_f = f.t.shape[0]
        hold = (lambda s: None if s is None else np.repeat(np.asarray(s, dtype=float), k)[:n_f])
        o_f = None if other is None else np.empty((other.shape[0], n_f))
        y, u, status = simulate_inputs(models, f, n_sub, hold(w), hold(noise), quant, o_f,
                                       effort=effort)
        if other is not None and o_f is not None:
            other[...] = o_f[:, ::k]
        return np.ascontiguousarray(y[:, ::k]), np.ascontiguousarray(u[:, ::k]), status
    n = int(inp.t.shape[0])
    # the rows of one call that share a controller (a finite-difference Jacobian) convert it
    # once: the first controller of a value in the call gives the law of all that equal it
    local: dict[object, tuple] = {}
    parts = []
    laws: list[PositionalLaw | None] = []
    sources = []
    for m in models:
        # a parametric loop whose drive clips runs in positional form (its integral held
        # while clipped); an identified law recurses on the clipped effort it was fitted to,
        # unless it was chosen clamped
        pos = ((isinstance(m.controller, CascadeController)
                or (isinstance(m.controller, ArxController) and m.controller.clamped))
               and bool(np.isfinite(m.plant[CL.I_IMAX])))
        key = ((m.controller, pos) if isinstance(m.controller, CascadeController)
               else (id(m.controller), pos))
        if key not in local:
            local[key] = _FREE_RUNS.law(inp, m.controller, pos)
        source, part, law = local[key]
        parts.append(part)
        laws.append(law)
        sources.append(source)
    na = max(p[0].shape[0] for p in parts)
    nc = max(p[1].shape[0] for p in parts)
    n_rows = len(models)
    pads: tuple[int, int] | None = None
    if any(law is not None for law in laws):
        pads = (max(law.a2.shape[0] for law in laws if law is not None),
                max(law.c2.shape[0] for law in laws if law is not None))
    # free runs already simulated on these inputs (noise-free only): a row's run depends on
    # its plant, its law and the padded widths of the batch's law arrays, nothing else of
    # the batch (each row runs alone in the kernel)
    keys: list[tuple | None] = [None] * n_rows
    if noise is None and quant == 0.0:
        keys = [(src, m.plant.tobytes(), int(n_sub), na, nc,
                 pads if law is not None else None, None if w is None else id(w))
                for m, src, law in zip(models, sources, laws, strict=True)]
    todo: list[int] = []
    first: dict[tuple, int] = {}
    same: list[tuple[int, int]] = []
    hits: list[tuple[int, tuple]] = []
    for i, rk in enumerate(keys):
        hit = None if rk is None else _FREE_RUNS.run(inp, rk, m=models[i], w=w,
                                                       other=other is not None, effort=effort)
        if hit is not None:
            hits.append((i, hit))
        elif rk is not None and rk in first:
            same.append((i, first[rk]))
        else:
            if rk is not None:
                first[rk] = i
            todo.append(i)
    if len(todo) == n_rows:
        # every row simulated (a Jacobian's batch, as a rule): the kernel's arrays are the
        # outputs, rather than copies of them into new ones
        out = other
        if other is not None and (other.dtype != np.float64 or not other.flags.c_contiguous):
            out = np.empty((n_rows, n))
        Y, U, status, _ = _simulate_rows(models, parts, laws, inp, n_sub, na, nc, pads, w,
                                         noise, quant, out)
        if other is not None and out is not other:
            other[...] = out
        for i, rk in enumerate(keys):
            if rk is not None:
                _FREE_RUNS.store(inp, rk, models[i], w, Y[i], U[i] if effort else None,
                                 None if out is None else out[i], int(status[i]))
        return Y, U, status
    Y = np.empty((n_rows, n))
    U = np.empty((n_rows, n))
    status = np.zeros(n_rows, dtype=np.int64)
    for i, hit in hits:
        Y[i], U[i], status[i] = hit[0], math.nan if hit[1] is None else hit[1], hit[3]
        if other is not None:
            other[i] = hit[2]
    if todo:
        o_todo = None if other is None else np.empty((len(todo), n))
        y, u, st, y2 = _simulate_rows([models[i] for i in todo], [parts[i] for i in todo],
                                      [laws[i] for i in todo], inp, n_sub, na, nc, pads, w,
                                      noise, quant, o_todo)
        for j, i in enumerate(todo):
            Y[i], U[i], status[i] = y[j], u[j], st[j]
            if other is not None and y2 is not None:
                other[i] = y2[j]
            rk = keys[i]
            if rk is not None:
                _FREE_RUNS.store(inp, rk, models[i], w, y[j], u[j] if effort else None,
                                 None if y2 is None else y2[j], int(st[j]))
    for i, j in same:
        Y[i], U[i], status[i] = Y[j], U[j], status[j]
        if other is not None:
            other[i] = other[j]
    return Y, U, status


def _simulate_rows(models: Sequence[GreyBox], parts: Sequence[tuple],
                   laws: Sequence[PositionalLaw | None], inp: LoopInputs, n_sub: int,
                   na: int, nc: int, pads: tuple[int, int] | None, w: np.ndarray | None,
                   noise: np.ndarray | None, quant: float, other: np.ndarray | None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """One batch of the kernel: ``models`` with their laws' arrays padded to ``na``, ``nc``
    (and ``pads`` for the positional laws' increments); ``other``, when given, receives the
    other encoder's position. Returns ``(y, u, status, other)``."""
    n = int(inp.t.shape[0])
    n_rows = len(models)
    A = np.zeros((n_rows, na))
    C = np.zeros((n_rows, nc))
    U0 = np.zeros((n_rows, na))
    y_init = inp.history(max(nc, 1))
    # the rows that share a law (the same arrays: one controller of the call) share its
    # reference parts in the kernel: one copy of each K-sample array per law, not per row
    index: dict[tuple[int, int], int] = {}
    firsts: list[int] = []  # the first row of each law
    law_index = np.empty(n_rows, dtype=np.int64)
    for i, (part, law) in enumerate(zip(parts, laws, strict=True)):
        a, c, _, u0, _ = part
        A[i, : a.shape[0]] = a
        C[i, : c.shape[0]] = c
        U0[i, : u0.shape[0]] = u0
        j = index.setdefault((id(part), id(law)), len(firsts))
        if j == len(firsts):
            firsts.append(i)
        law_index[i] = j
    R = np.empty((len(firsts), n))
    for j, i in enumerate(firsts):
        R[j] = parts[i][2]
    P = np.stack([m.plant for m in models])
    extra: dict[str, np.ndarray] = {}
    if pads is not None and any(law is not None for law in laws):
        na2, nc2 = pads
        extra = {"positional": np.array([law is not None for law in laws]),
                 "a2": np.zeros((n_rows, na2)), "c2": np.zeros((n_rows, nc2)),
                 "r2": np.zeros((len(firsts), n)), "g_init": np.zeros((n_rows, na2)),
                 "i_init": np.zeros(n_rows)}
        for i, law in enumerate(laws):
            if law is None:
                continue
            extra["a2"][i, : law.a2.shape[0]] = law.a2
            extra["c2"][i, : law.c2.shape[0]] = law.c2
            extra["g_init"][i, : law.g_init.shape[0]] = law.g_init
            extra["i_init"][i] = law.i_init
        for j, i in enumerate(firsts):
            law = laws[i]
            if law is not None:
                extra["r2"][j] = law.r2
    y, u, status = CL.simulate_batch(P, A, C, R, inp.t, inp.ts, n_sub=n_sub, x0=inp.x0,
                                     v0=inp.v0, u_init=U0, y_init=y_init, w=w, noise=noise,
                                     quant=quant, other=other, law_index=law_index,
                                     parallel=(not getattr(_THREAD, "concurrent", False)
                                               or _RUNNING.threads < 2),
                                     **extra)  # type: ignore[arg-type]
    return y, u, status, other


_THREAD = threading.local()  # .concurrent: this thread runs a task of run_concurrently
_POOL: list[ThreadPoolExecutor] = []


class _Running:
    """Threads of :func:`run_concurrently` still running a task (the last one left runs its
    batches on numba's threads again)."""

    def __init__(self) -> None:
        self.threads = 0


_RUNNING = _Running()
# a forked child has none of its parent's threads: it starts a worker of its own
os.register_at_fork(after_in_child=_POOL.clear)


def run_concurrently(tasks: Sequence[Callable[[], _T]]) -> list[_T]:
    """The results of ``tasks``, independent computations (a fit on each fold, fits from
    several starts), in their order, run on two threads at once when the machine has two
    cores: the calling thread and one worker take the tasks in turn.

    The kernel releases the GIL, and a task's batches then run on its own thread (not on
    numba's, which the other task would wait for): while one task is in Python (the
    optimiser, the residuals) the other's free runs use the second core; once no task is
    left to take, the last one's batches run on numba's threads again. The results are
    the same numbers as the tasks one after the other: each task computes from its own
    inputs, a kept free run is handed back as computed, and BLAS holds one thread throughout
    (its thread count is the process's: a task's dense algebra must not depend on whether
    the other is inside an SVD). A task that calls this again runs its own tasks in turn.
    An exception is raised once every task has ended: the first task's, in their order, that
    raised one (the one the tasks in turn would have raised).
    """
    if len(tasks) < 2 or getattr(_THREAD, "concurrent", False) or (os.cpu_count() or 1) < 2:
        return [task() for task in tasks]
    with _LOCK:
        if not _POOL:
            _POOL.append(ThreadPoolExecutor(max_workers=1, thread_name_prefix="diagnose"))
    pool = _POOL[0]
    results: list[_T | None] = [None] * len(tasks)
    errors: list[BaseException | None] = [None] * len(tasks)
    order = iter(range(len(tasks)))
    take = threading.Lock()
    _RUNNING.threads = 2

    def drain() -> None:
        _THREAD.concurrent = True
        try:
            while True:
                with take:
                    i = next(order, None)
                    if i is None:
                        # the last task left runs its batches on numba's threads again
                        _RUNNING.threads -= 1
                if i is None:
                    return
                try:
                    results[i] = tasks[i]()
                except BaseException as exc:  # noqa: BLE001 (raised below, in order)
                    errors[i] = exc
        finally:
            _THREAD.concurrent = False

    # a task whose kernel returns waits for the GIL until the other one's Python lets it go
    # (every switch interval, 5 ms by default: two single-row runs of a 40k-sample log):
    # half a millisecond while both run
    interval = sys.getswitchinterval()
    sys.setswitchinterval(min(interval, 5e-4))
    try:
        with one_blas_thread():
            # the worker's tasks end inside the BLAS limit too, whatever the caller's did
            worker = pool.submit(drain)
            drain()
            worker.result()
    finally:
        sys.setswitchinterval(interval)
    for exc in errors:
        if exc is not None:
            raise exc
    return cast(list[_T], results)


class _Lru:
    """Entries ``(bytes, ...)`` by key, the least recently used dropped beyond ``budget``
    bytes (no lock: :class:`_FreeRunCache` holds one)."""

    def __init__(self, budget: int) -> None:
        self.budget = budget
        self.entries: OrderedDict[tuple, tuple] = OrderedDict()
        self.bytes = 0

    def get(self, key: tuple) -> tuple | None:
        entry = self.entries.get(key)
        if entry is not None:
            self.entries.move_to_end(key)
        return entry

    def put(self, key: tuple, entry: tuple) -> None:
        old = self.entries.pop(key, None)
        if old is not None:
            self.bytes -= old[0]
        if entry[0] > self.budget:
            return
        self.entries[key] = entry
        self.bytes += entry[0]
        while self.bytes > self.budget:
            self.bytes -= self.entries.popitem(last=False)[1][0]

    def drop(self, first: int) -> None:
        """Drop the entries whose key starts with ``first``."""
        for key in [key for key in self.entries if key[0] == first]:
            self.bytes -= self.entries.pop(key)[0]


class _FreeRunCache:
    """The laws and noise-free free runs already computed on each set of loop inputs.

    The search simulates the same model many times: the fits of both folds start from the same
    model (their first Jacobian is the same batch of runs), a model's size is measured on the
    run its fit has just simulated, the screens and starts try the same grids. A run is a pure
    function of its plant row, its law and the padded widths of its batch's law arrays, so it
    is kept by those (the row's bytes, the law's exact parameters) and handed back as it was
    computed. Least recently used entries go first once ``budget`` bytes are held; the entries
    of a set of inputs go with it. Only the arrays are kept, never handed out: callers get
    copies. The laws (a Jacobian's rows of the loop's gains are a new law each, cheap to
    convert again) are kept apart, within ``law_budget``, so that they do not push runs out.

    Parameters
    ----------
    budget : int
        Bytes of runs' outputs held at most.
    law_budget : int
        Bytes of laws' arrays held at most.
    """

    def __init__(self, budget: int = 256 * 2**20, law_budget: int = 32 * 2**20) -> None:
        self._stores = {"run": _Lru(budget), "law": _Lru(law_budget)}
        # reentrant: a set of inputs collected while its thread holds the lock (a cycle
        # freed by the collector inside put) drops its entries from that thread
        self._lock = threading.RLock()
        self._inputs: set[int] = set()

    def _watch(self, inp: LoopInputs) -> int:
        """The key of ``inp``, its entries dropped when it is collected."""
        k = id(inp)
        with self._lock:
            if k not in self._inputs:
                self._inputs.add(k)
                weakref.finalize(inp, self._drop, k)
        return k

    def _drop(self, k: int) -> None:
        with self._lock:
            self._inputs.discard(k)
            for store in self._stores.values():
                store.drop(k)

    def _get(self, key: tuple) -> tuple | None:
        with self._lock:
            return self._stores[key[1]].get(key)

    def _put(self, key: tuple, entry: tuple) -> None:
        with self._lock:
            self._stores[key[1]].put(key, entry)

    def law(self, inp: LoopInputs, ctrl: CascadeController | ArxController, pos: bool
            ) -> tuple[tuple, tuple, PositionalLaw | None]:
        """``(source, arrays, positional law)`` of ``ctrl`` on ``inp``: ``source`` names the
        law exactly (a cascade's parameters to the bit, an identified law by identity)."""
        if isinstance(ctrl, CascadeController):
            source: tuple = ("cascade", pos, np.array([getattr(ctrl, f) for f in _CASCADE_FIELDS],
                                                      dtype=float).tobytes())
        else:
            source = ("arx", pos, id(ctrl))
        key = (self._watch(inp), "law", source)
        entry = self._get(key)
        # an identified law is known by identity: the entry holds it, so its id is not reused
        if entry is not None and (isinstance(ctrl, CascadeController) or entry[1] is ctrl):
            return source, entry[2], entry[3]
        plaw: PositionalLaw | None = None
        if pos:
            plaw = ctrl.positional(inp)
            arrays = (plaw.a, plaw.c, plaw.r, plaw.q_init, plaw.y_init)
        else:
            arrays = ctrl.arx(inp)
        size = sum(a.nbytes for a in arrays) + (0 if plaw is None else plaw.r2.nbytes)
        self._put(key, (size, ctrl, arrays, plaw))
        return source, arrays, plaw

    def run(self, inp: LoopInputs, key: tuple, *, m: GreyBox, w: np.ndarray | None,
            other: bool, effort: bool) -> tuple | None:
        """``(y, u, other, status)`` of a run kept under ``key``, or None (``u`` None when
        it was kept without its effort, and ``effort`` is False)."""
        entry = self._get((self._watch(inp), "run", key))
        if entry is None or entry[1] is not w:
            return None
        if key[0][0] == "arx" and entry[2] is not m.controller:
            return None
        if (other and entry[5] is None) or (effort and entry[4] is None):
            return None
        return entry[3], entry[4], entry[5], entry[6]

    def store(self, inp: LoopInputs, key: tuple, m: GreyBox, w: np.ndarray | None,
              y: np.ndarray, u: np.ndarray | None, other: np.ndarray | None, status: int
              ) -> None:
        """Keep a run (copies of its rows) under ``key`` (without its effort: ``u`` None)."""
        size = y.nbytes + sum(a.nbytes for a in (u, other) if a is not None)
        # the entry holds ``w`` and an identified law: the ids in its key stay theirs
        self._put((self._watch(inp), "run", key),
                  (size, w, m.controller, y.copy(), None if u is None else u.copy(),
                   None if other is None else other.copy(), status))


_FREE_RUNS = _FreeRunCache()
_CASCADE_FIELDS = tuple(f.name for f in dataclasses.fields(CascadeController))


def simulate_position(model: GreyBox, prep: Prepared, w: np.ndarray | None = None,
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Free-run position (m) and effort of one model; NaN after a divergence."""
    y, u, _ = simulate_models([model], prep, w)
    return y[0], u[0]


def cascade_effort(ctrl: CascadeController | ArxController, prep: Prepared,
                   x: np.ndarray | None = None) -> np.ndarray:
    """Effort the controller computes from the *measured* position (virtual effort).

    Parameters
    ----------
    ctrl : CascadeController or ArxController
    prep : Prepared
    x : ndarray, optional
        Position fed back (default: the measured one), m.

    Returns
    -------
    ndarray, shape (K,)
    """
    xm = prep.x if x is None else x
    inp = prep.inputs
    if inp.n_loop > 1:
        # a loop faster than the log reads the position between the logged samples too
        f = inp.fine
        xm = np.interp(f.t, inp.t, xm)
        a, c, r, u_init, y_init = ctrl.arx(f)
    else:
        a, c, r, u_init, y_init = ctrl.arx(inp)
    nc = c.shape[0]
    # xpad[nc - 1 + k] = x[k]; the samples before the run come from y_init = x[-1], x[-2], ...
    xpad = np.concatenate([y_init[: nc - 1][::-1], xm])
    fb = r + np.convolve(xpad, c, mode="valid")[: xm.shape[0]] if nc else r.copy()
    if a.shape[0] == 0:
        return fb
    den = np.concatenate([[1.0], -a])
    zi = signal.lfiltic([1.0], den, u_init)
    out, _ = signal.lfilter([1.0], den, fb, zi=zi)
    return out[:: inp.n_loop] if inp.n_loop > 1 else out


# -- output-error fit ---------------------------------------------------------------------------
def _damping_param(b: Bounds) -> Param:
    """The viscous damping ``B`` of every model (not an effect): 0 .. ``b.damping_max``."""
    return Param(CL.I_B, False, 0.0, b.damping_max, b.damping_scale)


def position_params(model: GreyBox, b: Bounds, *, controller: bool,
                    effects: Iterable[str] | None = None, damping: bool = True,
                    controller_box: float | None = None, ki_min_ratio: float = 0.0
                    ) -> list[Param]:
    """Free parameters of an output-error fit.

    Parameters
    ----------
    model : GreyBox
    b : Bounds
    controller : bool
        Free the cascade controller (only for :class:`CascadeController`).
    effects : iterable of str, optional
        Effects whose parameters are free (default: all of the model's).
    damping : bool
        Free the viscous damping ``B``.
    controller_box : float, optional
        Keep each controller gain within this factor of its current value (feedforward
        fractions within +-0.1 per unit of the factor above 1). Without it, only the physical
        ranges of a servo loop apply.
    ki_min_ratio : float
        Smallest integral rate, as a fraction of the velocity-loop gain ``wv``.
    """
    out: list[Param] = []
    if controller and isinstance(model.controller, CascadeController):
        ts = b.controller_ts
        c = model.controller
        # a servo loop: velocity bandwidth wv 3 % .. 200 % of the sampling rate (rad/s),
        # position gain 2 % .. 200 % of wv (a position loop much faster than the velocity loop
        # inside it does not work), integral rate 2 % .. 50 % of wv (an integral time of at
        # most 50 loop time constants: without an effort the integral action is hardly
        # identifiable, and a loop without it lets Coulomb friction imitate backlash),
        # feedforward up to 1.5
        rp, ri = c.kp / c.wv, c.ki / c.wv
        lim = {"wv": (0.03 / ts, 2.0 / ts), "kp": (0.02, 2.0), "ki": (defaults().ki_min_ratio, 0.5),
               "kvff": (0.0, 1.5), "kaff": (0.0, 1.5)}
        if controller_box is not None:
            f = float(controller_box)
            d = 0.1 * (f - 1.0)
            box = {"wv": (c.wv / f, c.wv * f), "kp": (rp / f, rp * f),
                   # an integral action cannot be fitted away (friction would then imitate
                   # backlash), but an integral rate a linear fit could not see (it hardly
                   # shows without a disturbance) may rise to a usual value, a quarter of wv
                   "ki": (ri / f, max(ri * f, 0.25)),
                   "kvff": (c.kvff - d, c.kvff + d), "kaff": (c.kaff - d, c.kaff + d)}
            lim = {k: (max(lim[k][0], box[k][0]), min(lim[k][1], box[k][1])) for k in lim}
        lim["ki"] = (max(lim["ki"][0], min(ki_min_ratio, 0.25)), lim["ki"][1])
        if c.is_pid:
            # a PID position loop: its integral acts on the position error (kpi, up to
            # 2 wv^2: beyond P D an integral destabilises the loop) and its derivative
            # through a filter of up to 20 samples (a pole of 0.95); no velocity-loop integral
            rpi = c.kpi / c.wv**2
            lim["kpi"] = (defaults().pid_kpi_min_ratio, 2.0)
            lim["vel_pole"] = (0.0, 0.95)
            if controller_box is not None:
                f = float(controller_box)
                d = 0.1 * (f - 1.0)
                lim["kpi"] = (max(lim["kpi"][0], rpi / f), min(lim["kpi"][1], rpi * f))
                lim["vel_pole"] = (max(0.0, c.vel_pole - d), min(0.95, c.vel_pole + d))
        lim = {k: (lo, hi) if hi > lo else (lo, lo * (1 + 1e-9) + 1e-12)
               for k, (lo, hi) in lim.items()}
        out += [
            Param("wv", True, *lim["wv"], 1.0),
            Param("kp_per_wv", True, *lim["kp"], 1.0),
        ]
        if c.is_pid:
            out += [Param("kpi_per_wv2", True, *lim["kpi"], 1.0),
                    Param("vel_pole", False, *lim["vel_pole"], 0.2)]
        else:
            out.append(Param("ki_per_wv", False, *lim["ki"], 0.05))
        out += [
            Param("kvff", False, *lim["kvff"], 0.5),
            Param("kaff", False, *lim["kaff"], 0.5),
        ]
    if damping:
        out.append(_damping_param(b))
    for e in (model.effects if effects is None else effects):
        effect = get_effect(e)
        held = effect.held(model.plant)
        for i in effect.free(model.effects) + effect.conditional(model.plant):
            if i not in held:
                out.append(effect.bounds(i, float(model.plant[i]), b))
    return out


def _with_values(model: GreyBox, params: Sequence[Param], values: Sequence[float]) -> GreyBox:
    ctrl_changes = {}
    plant = model.plant.copy()
    for prm, val in zip(params, values, strict=True):
        if isinstance(prm.target, str):
            ctrl_changes[prm.target] = float(val)
        else:
            plant[prm.target] = float(val)
    ctrl = model.controller
    if ctrl_changes and isinstance(ctrl, CascadeController):
        wv = ctrl_changes.get("wv", ctrl.wv)
        for key in ("kp", "ki"):
            # gains given relative to the velocity-loop bandwidth
            ratio = ctrl_changes.pop(f"{key}_per_wv", None)
            if ratio is not None:
                ctrl_changes[key] = ratio * wv
        ratio = ctrl_changes.pop("kpi_per_wv2", None)
        if ratio is not None:
            ctrl_changes["kpi"] = ratio * wv * wv
        ctrl = ctrl.with_values(**ctrl_changes)
    return model.copy(controller=ctrl, plant=plant)


def _lm_box(params: Sequence[Param], model: GreyBox
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Start, bounds and finite-difference steps of an output-error fit, in theta space."""
    theta0 = np.array([p.to_theta(p.get(model)) for p in params])
    lo = np.array([p.bounds()[0] for p in params])
    hi = np.array([p.bounds()[1] for p in params])
    steps = np.minimum(np.where([p.log for p in params], 2e-3, 1e-3), 0.05 * (hi - lo))
    return theta0, lo, hi, steps


def _models_at(base: GreyBox, params: Sequence[Param], thetas: np.ndarray) -> list[GreyBox]:
    """``base`` with the free parameters set to each row of ``thetas``."""
    return [_with_values(base, params, [p.from_theta(t) for p, t in zip(params, th, strict=True)])
            for th in thetas]


@dataclass
class PositionFitResult:
    """Outcome of :meth:`PositionFit.run`."""

    model: GreyBox
    y: np.ndarray
    cost: float
    n_iter: int
    jac_rows: np.ndarray | None = field(default=None, repr=False)


class PositionFit:
    """Output-error least squares of selected parameters on the measured position.

    Parameters
    ----------
    prep : Prepared
    params : list of Param
        Free parameters.
    mask : ndarray of bool, optional
        Samples whose error is minimised (default: all).
    w : ndarray, optional
        Injected effort of the run.
    """

    def __init__(self, prep: Prepared, params: list[Param], mask: np.ndarray | None = None,
                 w: np.ndarray | None = None) -> None:
        self.prep = prep
        self.params = params
        self.mask = np.ones(prep.n, dtype=bool) if mask is None else mask
        self.w = w
        self.scale = max(prep.noise.rms, 1e-9)
        self._cache: tuple[np.ndarray, np.ndarray] | None = None

    def _resid(self, y: np.ndarray, y_load: np.ndarray | None = None) -> np.ndarray:
        r = (self.prep.x - y)[self.mask] / self.scale
        if y_load is not None and self.prep.x_load is not None:
            # a load encoder: its error joins the motor encoder's, at the same noise scale
            r = np.concatenate([r, (self.prep.x_load - y_load)[self.mask] / self.scale])
        bad = ~np.isfinite(r)
        if bad.any():
            r = np.where(bad, _DIVERGED, r)
        return r

    def _resids(self, ys: np.ndarray, loads: np.ndarray | None) -> np.ndarray:
        """:meth:`_resid` of every row of ``ys`` (and ``loads``) at once, the same numbers."""
        # compress keeps the rows C-contiguous (a boolean index on axis 1 would not), as the
        # per-row arrays were: the Jacobian's layout, and so its BLAS rounding, stays
        r = (self.prep.x[None, :] - ys).compress(self.mask, axis=1) / self.scale
        if loads is not None and self.prep.x_load is not None:
            r = np.concatenate([r, (self.prep.x_load[None, :] - loads).compress(self.mask, axis=1)
                                / self.scale], axis=1)
        bad = ~np.isfinite(r)
        if bad.any():
            r = np.where(bad, _DIVERGED, r)
        return r

    def _simulate(self, models: list[GreyBox]) -> tuple[np.ndarray, np.ndarray | None]:
        """Logged positions of ``models`` and, with a load encoder, their load positions."""
        other = None
        if self.prep.x_load is not None:
            other = np.empty((len(models), self.prep.n))
        ys, _, _ = simulate_models(models, self.prep, self.w, other=other, effort=False)
        return ys, other

    def run(self, model: GreyBox, max_iter: int = 15, *, jacobian: bool = False
            ) -> PositionFitResult:
        """Fit from ``model``'s current values; returns the fitted model and its position.

        With ``jacobian`` the result keeps the Jacobian at its end point (``jac_rows``);
        without it a fit that ends on ``max_iter`` does not simulate that last Jacobian
        (:func:`~fricbench.sysid.diagnose.leastsq.bounded_least_squares`), and ``jac_rows``
        may be None. The fitted values are the same numbers either way.

        A parameter whose bounds are a trust region (:attr:`Param.trust`) and that ends on
        one is fitted again with the region moved to its end point, up to
        ``settings.trust_walks`` times, while the cost falls. A spectral period off by more than
        the region's width otherwise stays on its edge, and another effect takes up the beat
        of the two periods along the stroke (the second simulator's cogging/24: a period 4 %
        long, and a friction varying along the stroke named beside it).
        """
        res = self._run_once(model, max_iter, jacobian)
        params = self.params
        for _ in range(defaults().trust_walks):
            moved = [p.recentred(p.get(res.model)) if p.trust and p.on_bound(p.get(res.model))
                     else p for p in params]
            if all(a is b for a, b in zip(moved, params, strict=True)):
                break
            params = moved
            walked = PositionFit(self.prep, params, self.mask, self.w)._run_once(
                res.model, max_iter, jacobian)
            if not walked.cost < res.cost:
                break
            res = walked
        return res

    def _run_once(self, model: GreyBox, max_iter: int, jacobian: bool = True
                  ) -> PositionFitResult:
        if not self.params:
            ys, loads = self._simulate([model])
            r = self._resid(ys[0], None if loads is None else loads[0])
            return PositionFitResult(model, ys[0], 0.5 * sumsq(r), 0)
        theta0, lo, hi, steps = _lm_box(self.params, model)
        last: dict[str, np.ndarray] = {}

        def residuals(thetas: np.ndarray) -> np.ndarray:
            ys, loads = self._simulate(_models_at(model, self.params, thetas))
            if thetas.shape[0] == 1:
                last["theta"], last["y"] = thetas[0].copy(), ys[0]
            else:
                last.setdefault("batch", ys)
                last["batch"], last["thetas"] = ys, thetas.copy()
            return self._resids(ys, loads)

        sol = bounded_least_squares(residuals, theta0, lo, hi, steps, max_iter=max_iter,
                                    final_jacobian=jacobian)
        fitted = _models_at(model, self.params, sol.x[None, :])[0]
        y = None  # type: ignore[assignment]
        if "theta" in last and np.array_equal(last["theta"], sol.x):
            y = last["y"]
        elif "thetas" in last:
            hit = np.flatnonzero(np.all(last["thetas"] == sol.x[None, :], axis=1))
            if hit.size:
                y = last["batch"][hit[0]]
        if y is None:
            y = simulate_position(fitted, self.prep, self.w)[0]
        return PositionFitResult(fitted, y, float(sol.cost), int(sol.njev),
                                 None if sol.jac is None else sol.jac.T)


def _go_on(fit: PositionFit, model: GreyBox) -> PositionFit:
    """``fit`` to go on from ``model``, where its heat ended: a trust region the heat walked
    out of (:meth:`PositionFit.run`) is centred on the value it walked to."""
    params = [p.recentred(p.get(model)) if p.trust and not p.lo <= p.get(model) <= p.hi else p
              for p in fit.params]
    if all(a is b for a, b in zip(params, fit.params, strict=True)):
        return fit
    return PositionFit(fit.prep, params, fit.mask, fit.w)


def race_fits(fits: Sequence[tuple[PositionFit, GreyBox]], max_iter: int, *,
              family: Callable[[GreyBox], object] | None = None,
              eligible: Callable[[int, PositionFitResult], bool] | None = None,
              share: float | None = None) -> list[PositionFitResult | None]:
    """Each ``(fit, start)`` fitted for up to ``max_iter`` iterations, the starts racing:
    every one runs ``share`` of them (its heat; ``settings.race_share`` when None), then the
    best ``share`` of the heats of each ``family`` (one family when None; at least one),
    among the heats for which ``eligible(i, heat)`` is true, run the rest from where they
    ended: one round of successive halving, eta = 1 / share.

    Returns one entry per start, in their order: the finalists' fits, None for the others
    (a single start, or a share of 1: every start's whole fit; no heat finite
    or eligible: the heats). Starts of a fit that has several minima land in different
    basins within a few iterations, and the rest of the budget only refines one: every start
    running the whole budget spends free runs on basins it then throws away (the
    friction-aware loop's starts and the drive limit's were 36 % of the timing run's work,
    the effects' fold fits from several starts most of the rest). A start behind after its
    heat is not always the worse one at the end, though: at a third the held-out sets fell
    by one run each (when only each family's best heat went on), and the default share is 1
    (no race) but in the drive limit's fits (``settings.limit_race_share``). There, with the
    drive limit's grid of Coulomb forces (17 starts), the best heat alone went on to worse
    ends than a third of them (the second simulator's development run control/906: the
    squared error with the limit 15 % of that without it, against 7.5 %).
    """
    share = defaults().race_share if share is None else share
    heat = max(1, min(max_iter, round(share * max_iter)))
    if len(fits) == 1:
        heat = max_iter
    heats = run_concurrently([partial(f.run, start, max_iter=heat) for f, start in fits])
    if heat >= max_iter:
        return list(heats)
    groups: dict[object, list[int]] = {}
    for i, res in enumerate(heats):
        if not np.isfinite(res.cost) or (eligible is not None and not eligible(i, res)):
            continue
        groups.setdefault(None if family is None else family(res.model), []).append(i)
    if not groups:
        return list(heats)
    # successive halving's one round: the best ``share`` of each family's heats go on (the
    # rate its heat runs at, eta = 1 / share), at least one
    finalists = sorted(i for group in groups.values() for i in sorted(
        group, key=lambda j: heats[j].cost)[:max(1, math.ceil(share * len(group)))])
    finals = run_concurrently([partial(_go_on(fits[i][0], heats[i].model).run, heats[i].model,
                                       max_iter=max_iter - heat) for i in finalists])
    out: list[PositionFitResult | None] = [None] * len(fits)
    for i, res in zip(finalists, finals, strict=True):
        out[i] = res
    return out


class JointPositionFit:
    """Output-error least squares of one model on several runs of the same axis.

    The residuals of every run (each scaled by its own noise floor) are stacked, so a
    parameter set must explain all runs at once; each run starts from its own initial state.

    Parameters
    ----------
    preps : sequence of Prepared
    params : list of Param
        Free parameters.
    """

    def __init__(self, preps: Sequence[Prepared], params: list[Param]) -> None:
        if not preps:
            raise ValueError("preps is empty: expected at least one prepared run")
        self.preps = list(preps)
        self.params = params

    def residuals(self, models: Sequence[GreyBox]) -> np.ndarray:
        """Stacked scaled residuals of each model, shape (len(models), total samples)."""
        parts = []
        for prep in self.preps:
            ys, _, _ = simulate_models(models, prep, effort=False)
            r = (prep.x[None, :] - ys) / max(prep.noise.rms, 1e-9)
            parts.append(np.where(np.isfinite(r), r, _DIVERGED))
        return np.concatenate(parts, axis=1)

    def run(self, model: GreyBox, max_iter: int = 15) -> tuple[GreyBox, float]:
        """Fit from ``model``'s current values; returns the fitted model and its cost."""
        if not self.params:
            return model, 0.5 * sumsq(self.residuals([model])[0])
        theta0, lo, hi, steps = _lm_box(self.params, model)
        sol = bounded_least_squares(
            lambda th: self.residuals(_models_at(model, self.params, th)), theta0, lo, hi,
            steps, max_iter=max_iter)
        return _models_at(model, self.params, sol.x[None, :])[0], float(sol.cost)


# -- inverse dynamics ---------------------------------------------------------------------------
class InverseDynamics:
    """Least-squares inverse dynamics ``u = M a + B v + F_eff(x, v)`` (IDIM-LS).

    Columns are built at the full rate from the filtered motion of ``prep`` and decimated in
    parallel with the effort; the fit and its error are computed on the decimated rows.

    Parameters
    ----------
    prep : Prepared
    u : ndarray, shape (K,)
        Effort (measured, or the controller's virtual effort).
    label : str
        Cache key of this effort.
    delay : int
        Samples the effort takes to act (a drive's command delay, the plant's ``I_DELAY``):
        the effort of sample ``k - delay`` is regressed on the motion of sample ``k``.

    Notes
    -----
    The effort is a command held over a loop period (a zero-order hold, as the simulated
    drive applies it), while the acceleration comes from zero-phase differences centred on
    the sample: the regressor is the effort half a loop period late,
    ``(1 - h) u[k - delay] + h u[k - delay - 1]`` with ``h = 0.5 / n_loop``. Without it the
    regression was half a sample early: on EMPS the cross-tested effort error was 5.67 %
    (3.86 % with it), and a PD loop's damping came out 0.7-1.4 % low (0.1-0.2 %).
    """

    def __init__(self, prep: Prepared, u: np.ndarray, label: str = "u", delay: int = 0
                 ) -> None:
        if isinstance(delay, bool) or not isinstance(delay, (int, np.integer)) or delay < 0:
            raise ValueError(f"delay={delay!r}: expected an integer number of samples >= 0")
        self.prep = prep
        self.delay = int(delay)
        if self.delay > 0:
            u = np.concatenate([np.full(self.delay, u[0]), u[:-self.delay]])
            label = f"{label}-delayed-{self.delay}"
        # a zero-order hold: the command of sample k acts over the next loop period, so the
        # zero-phase acceleration at k sees it half a loop period late (half a log sample at
        # the loop's rate, 0.5 / n_loop of one when the loop runs n_loop times faster)
        alpha = 0.5 / max(int(prep.inputs.n_loop), 1)
        u = (1.0 - alpha) * np.asarray(u, dtype=float) + alpha * np.concatenate([u[:1], u[:-1]])
        self.label = label
        self.u_dec = prep.dec(("effort", label), u)
        self.a_dec = prep.dec("a", prep.af)
        self.v_dec = prep.dec("v", prep.vf)
        self.x_dec = prep.dec("x", prep.xf)
        self.n_dec = self.u_dec.shape[0]
        self._layouts: dict[object, tuple[tuple[int, ...], np.ndarray]] = {}

    # ---- prediction with the exact force law
    def predict(self, p: np.ndarray) -> np.ndarray:
        """Decimated effort predicted by plant row ``p``."""
        force = p[CL.I_M] * self.prep.af + CL.sliding_force(p, self.prep.xf, self.prep.vf)
        return decimate_columns(force, self.prep.decim)

    def relerr(self, p: np.ndarray, rows: np.ndarray | None = None) -> float:
        """``100 ||u - u_hat|| / ||u||`` on the decimated rows (all, or ``rows``)."""
        r = self.u_dec - self.predict(p)
        if rows is not None:
            return float(100.0 * np.sqrt(sumsq(r[rows]) / sumsq(self.u_dec[rows])))
        return float(100.0 * np.sqrt(sumsq(r) / sumsq(self.u_dec)))

    # ---- regression
    def _columns(self, name: str, p: np.ndarray, effects: tuple[str, ...]
                 ) -> tuple[np.ndarray, tuple[int, ...], np.ndarray]:
        effect = get_effect(name)
        key = ("col", name, *effect.idim_key(p, effects))
        if key not in self._layouts:
            cols, targets, scale = effect.idim_columns(p, effects, self.prep.xf, self.prep.vf)
            self.prep.dec(key, cols)
            self._layouts[key] = (targets, scale)
        targets, scale = self._layouts[key]
        return self.prep.dec(key), targets, scale

    def design(self, effects: tuple[str, ...], p: np.ndarray
               ) -> tuple[np.ndarray, list[tuple[int, float]]]:
        """Decimated regressors of the model with ``effects``; layout of the coefficients."""
        cols = [self.a_dec[:, None], self.v_dec[:, None]]
        layout: list[tuple[int, float]] = [(CL.I_M, 1.0), (CL.I_B, 1.0)]
        for e in effects:
            if get_effect(e).kind != "force":
                continue
            c, targets, scale = self._columns(e, p, effects)
            cols.append(c)
            layout += list(zip(targets, scale, strict=True))
        return np.hstack(cols), layout

    def _solve(self, effects: tuple[str, ...], p: np.ndarray, rows: np.ndarray
               ) -> tuple[np.ndarray, float]:
        X, layout = self.design(effects, p)
        # physical signs: mass, damping and friction levels are not negative
        keep = {CL.I_M, CL.I_B}.union(*(get_effect(e).nonnegative for e in effects))
        nonneg = np.array([t in keep for t, _ in layout])
        Xr, ur = X[rows], self.u_dec[rows]
        coef = solve_ls(Xr, ur, nonneg)
        out = p.copy()
        for (target, s), cf in zip(layout, coef, strict=True):
            out[target] = cf * s if s != 0.0 else 0.0
        if any(s == 0.0 for _, s in layout):
            # coefficients of a relative change of the friction level: divide by the level
            fc = out[CL.I_FC]
            for (target, s), cf in zip(layout, coef, strict=True):
                if s == 0.0:
                    out[target] = cf / fc if abs(fc) > 1e-12 else 0.0
        return out, sumsq(ur - matvec(Xr, coef))

    def _search_nonlinear(self, name: str, effects: tuple[str, ...], p: np.ndarray,
                          rows: np.ndarray, start: bool) -> np.ndarray:
        """Refine (``start=False``) or find (``start=True``) the nonlinear parameter of an
        effect by variable projection on ``rows``."""
        effect = get_effect(name)
        idx = effect.idim_nonlinear
        if idx is None:
            raise ValueError(f"effect={name!r} has no nonlinear parameter")

        def sse_at(val: float) -> float:
            q = p.copy()
            q[idx] = val
            return self._solve(effects, q, rows)[1]

        grid = effect.idim_grid(self, effects, p, rows, start)
        if grid.size == 0:
            if start:
                # no start for its shape (no spatial period in the residual, say): the
                # effect cannot be fitted here, rather than fitted at a placeholder value
                raise NoStartError(f"{name}: no start for its nonlinear parameter on this run")
            return p
        best_val, best_sse = float(grid[0]), math.inf
        for g in grid:
            s = sse_at(float(g))
            if s < best_sse:
                best_val, best_sse = float(g), s
        # continuous refinement (log coordinate) around the best grid point
        bracket = effect.idim_bracket(best_val, grid, start)
        res = optimize.minimize_scalar(lambda lv: sse_at(math.exp(lv)), bounds=bracket,
                                       method="bounded", options={"xatol": 1e-4})
        out = p.copy()
        out[idx] = math.exp(res.x) if res.fun < best_sse else best_val
        return out

    def fit(self, effects: tuple[str, ...], p: np.ndarray, rows: np.ndarray | None = None,
            new: str | None = None) -> np.ndarray:
        """Least-squares plant row for ``effects`` on ``rows`` (default all).

        Nonlinear parameters are searched for the ``new`` effect and refined for the others.
        """
        rows = np.ones(self.n_dec, dtype=bool) if rows is None else rows
        rows = rows & self.prep.sliding_dec
        q = p.copy()
        for e in effects:
            q = get_effect(e).switched_on(q, self.prep)
        for e in effects:
            if get_effect(e).idim_nonlinear is not None:
                q = self._search_nonlinear(e, effects, q, rows, start=(e == new))
        out, _ = self._solve(effects, q, rows)
        return out

    def fit_levels(self, effects: tuple[str, ...], p: np.ndarray,
                   rows: np.ndarray | None = None) -> np.ndarray:
        """Least-squares mass, damping and force levels of the force effects among
        ``effects`` on ``rows`` (default all; sliding rows only), every other entry of ``p``
        held: the shapes, and the relative variations of the levels along the stroke
        (``Effect.relative_parameters``) that :meth:`fit` solves for.

        The force law is linear in those levels, away from the clamps that keep a level or the
        damping from turning negative: its columns are the law's derivatives at ``p`` by
        forward differences (a step up, off the clamp of a level at 0, where a central step
        halves the column), and ``p`` may be in other units than the effort (a model per unit
        mass).
        """
        rows = np.ones(self.n_dec, dtype=bool) if rows is None else rows
        rows = rows & self.prep.sliding_dec
        forces = [get_effect(e) for e in effects if get_effect(e).kind == "force"]
        levels = [CL.I_B] + sorted({i for e in forces for i in e.force_parameters} - {CL.I_B})
        keep = {CL.I_B}.union(*(e.nonnegative for e in forces))
        x, v = self.prep.xf, self.prep.vf
        step = 1e-3 * max(max(abs(float(p[i])) for i in levels), 1e-12)
        cols = [self.prep.af]
        at_p = CL.sliding_force(p, x, v)
        rest = at_p
        for i in levels:
            hi = p.copy()
            hi[i] += step
            col = (CL.sliding_force(hi, x, v) - at_p) / step
            cols.append(col)
            rest = rest - p[i] * col
        X = decimate_columns(np.column_stack(cols), self.prep.decim)
        lhs = self.u_dec - decimate_columns(rest, self.prep.decim)
        nonneg = np.array([True] + [i in keep for i in levels])
        coef = solve_ls(X[rows], lhs[rows], nonneg)
        out = p.copy()
        out[CL.I_M] = coef[0]
        out[levels] = coef[1:]
        return out

    def cv_sse(self, effects: tuple[str, ...], p: np.ndarray, new: str | None = None
               ) -> tuple[float, list[np.ndarray]]:
        """Held-out squared error: fit on one fold, evaluate on the other, both ways."""
        total, _, fits = self.cv_blocks(effects, p, new)
        return total, fits

    def cv_blocks(self, effects: tuple[str, ...], p: np.ndarray, new: str | None = None
                  ) -> tuple[float, np.ndarray, list[np.ndarray]]:
        """:meth:`cv_sse` and the same error per held-out block: the squared error on the
        sliding rows of each block (a contiguous run of one fold), fold 0's blocks first.
        Returns ``(total, per block, the two fold fits)``."""
        fd = self.prep.folds_dec
        ranges = fold_blocks(fd)
        total = 0.0
        blocks: list[float] = []
        fits = []
        for k in (0, 1):
            train = fd != k
            q = self.fit(effects, p, train, new)
            resid = self.u_dec - self.predict(q)
            total += sumsq(resid[~train & self.prep.sliding_dec])
            on = np.where(self.prep.sliding_dec, resid, 0.0)
            blocks += [sumsq(on[a:z]) for a, z in ranges if fd[a] == k]
            fits.append(q)
        return total, np.asarray(blocks, dtype=float), fits


def prediction_floor(model: GreyBox, prep: Prepared, w: np.ndarray | None = None,
                     seed: int = 0) -> float:
    """Rms position error a perfect deterministic model would still make on this run, m.

    The measured noise and quantisation (``prep.noise``) are injected into the model's sensors:
    the logged position carries them, and the loop reacts to them (with stiction, the moment
    of a breakaway depends on them). The rms difference to the noise-free simulation is the
    floor of a free-run prediction.
    """
    rng = np.random.default_rng(seed)
    noise = prep.noise.sigma * rng.standard_normal(prep.n)
    ys, _, status = simulate_models([model, model], prep, w)
    y_clean = ys[0]
    y_noisy = simulate_models([model], prep, w, noise=noise, quant=prep.noise.quantum)[0][0]
    d = y_noisy - y_clean
    if not np.all(np.isfinite(d)):
        return prep.noise.rms
    return float(max(np.sqrt(np.mean(d**2)), prep.noise.rms))
