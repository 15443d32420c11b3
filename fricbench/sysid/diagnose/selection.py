"""The one search: forward selection, then one backward pass, on the one criterion.

What a candidate *is* (its parameters, starts, fit and simulation) lives with the caller's
scorer; how hard the search looks lives here, as PySINDy keeps its feature library apart from
its optimiser. The search only sees structures (tuples of candidate names), their scores
(:class:`Scored`) and :func:`~fricbench.sysid.diagnose.criterion.criterion_change`.

1. **Forward**: every candidate whose prerequisites are in is scored added to the current
   structure, alone and with each candidate that refines it (requires it: a cogging with its
   second harmonic); the step that lowers the criterion most joins, while one does and the
   budget (:attr:`~fricbench.sysid.diagnose.settings.DiagnoseSettings.max_effects`) lasts. A
   greedy search cannot see a term whose cut shows only with its refinement (a ripple whose
   second order is 60 % of it cut a 6 s run's held-out error too little alone); the pair is
   judged by the same criterion, its penalty that of both. A step that breaks one of its
   plausibility constraints (:attr:`Scored.violation`) is not eligible, and the decision says
   why.
2. **Backward**, once: each candidate the forward pass added is scored removed from the final
   structure; it leaves when that does not raise the criterion (a later one made it redundant).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from fricbench.sysid.diagnose.criterion import criterion_change, effective_samples
from fricbench.sysid.diagnose.settings import DiagnoseSettings

__all__ = ["Candidate", "Scored", "Selection", "select"]


class Candidate(Protocol):
    """What the search needs of a candidate: a name and the names it requires."""

    @property
    def name(self) -> str:
        """Its name in structures and reports."""

    @property
    def requires(self) -> tuple[str, ...]:
        """Names that must be in the structure before it may join."""


@dataclass
class Scored:
    """A structure and its held-out error.

    Attributes
    ----------
    structure : tuple of str
        Candidate names in the model, in the order they joined.
    sse : float
        Held-out squared free-run error (inf: a held-out simulation diverged).
    n : int
        Held-out samples.
    k : int
        Fitted parameters.
    residual : ndarray
        The held-out residual (for the effective sample count).
    violation : str or None
        The plausibility constraint the fit broke (a parameter on its bound, ...).
    state : object
        Whatever the scorer keeps (its per-block fits, as starts for the next step).
    """

    structure: tuple[str, ...]
    sse: float
    n: int
    k: int
    residual: np.ndarray = field(repr=False)
    violation: str | None = None
    state: Any = field(default=None, repr=False)

    @property
    def rms(self) -> float:
        """Held-out rms error."""
        return math.sqrt(self.sse / self.n) if self.n and math.isfinite(self.sse) else math.inf


@dataclass
class Selection:
    """The structure the search chose and every decision it made.

    Attributes
    ----------
    best : Scored
    decisions : list of dict
        JSON-ready, in order: ``{"pass", "candidate", "heldout_rms", "n_params",
        "criterion_change", "n_eff", "accepted", "why"}`` (``criterion_change`` left out
        when the candidate diverged).
    scores : dict
        Held-out rms of every structure scored, keyed by its names joined with ``+``.
    """

    best: Scored
    decisions: list[dict[str, object]]
    scores: dict[str, float]


def _decision(pass_: str, name: str, sc: Scored, change: float, n_eff: float,
              accepted: bool, why: str) -> dict[str, object]:
    out: dict[str, object] = {"pass": pass_, "candidate": name, "n_params": sc.k,
                              "n_eff": n_eff, "accepted": accepted, "why": why}
    if math.isfinite(sc.rms):
        out["heldout_rms"] = sc.rms
    if math.isfinite(change):
        out["criterion_change"] = change
    return out


def _joined(step: Sequence[Candidate]) -> str:
    return "+".join(c.name for c in step)


def _steps(pool: Sequence[Candidate], structure: tuple[str, ...]
           ) -> list[tuple[Candidate, ...]]:
    """The forward steps from ``structure``: each candidate whose prerequisites are in, alone
    and with each candidate of ``pool`` that requires it and whose other prerequisites are in."""
    have = set(structure)
    out: list[tuple[Candidate, ...]] = []
    for cand in pool:
        if not set(cand.requires) <= have:
            continue
        out.append((cand,))
        out += [(cand, ref) for ref in pool if ref is not cand and cand.name in ref.requires
                and set(ref.requires) <= have | {cand.name}]
    return out


def select(base: Scored, candidates: Sequence[Candidate],
           score: Callable[[tuple[str, ...], Scored], Scored], settings: DiagnoseSettings,
           log: Callable[[str], None] | None = None,
           describe: Callable[[float], str] = lambda v: f"{v:.4g}") -> Selection:
    """Forward selection and one backward pass over ``candidates`` from ``base``.

    Parameters
    ----------
    base : Scored
        The starting structure, scored.
    candidates : sequence of Candidate
        Objects with ``name`` and ``requires`` (effects, loop structures).
    score : callable
        ``score(structure, current)`` fits and scores ``structure`` (``current``: the scored
        structure it grows or shrinks from, whose fits may serve as starts).
    settings : DiagnoseSettings
    log : callable, optional
        Progress lines.
    describe : callable
        Formats an rms error for the progress lines (the log's unit).
    """
    say = log or (lambda _s: None)
    current = base
    decisions: list[dict[str, object]] = []
    scores = {"+".join(base.structure): base.rms}
    added: list[str] = []
    pool = [c for c in candidates if c.name not in base.structure]
    while pool and len(added) < settings.max_effects:
        n_eff = effective_samples(current.residual, settings.max_lag_share)
        trials: list[tuple[float, tuple[Candidate, ...], Scored]] = []
        for step in _steps(pool, current.structure):
            if len(added) + len(step) > settings.max_effects:
                continue
            sc = score((*current.structure, *(c.name for c in step)), current)
            scores["+".join(sc.structure)] = sc.rms
            change = criterion_change(sc.sse, current.sse, sc.k, current.k, n_eff,
                                      settings.penalty)
            say(f"  + {_joined(step)}: held-out rms {describe(sc.rms)}, criterion "
                f"{change:+.3g}" + (f" ({sc.violation})" if sc.violation else ""))
            trials.append((change, step, sc))
        if not trials:
            break
        eligible = [t for t in trials if t[2].violation is None and math.isfinite(t[0])]
        for change, step, sc in trials:
            if sc.violation is not None:
                decisions.append(_decision("forward", _joined(step), sc, change, n_eff, False,
                                           f"constraint: {sc.violation}"))
        best = min(eligible, key=lambda t: t[0]) if eligible else None
        for change, step, sc in eligible:
            if best is not None and step is best[1] and change < 0.0:
                continue
            why = ("diverged on a held-out block" if not math.isfinite(change) else
                   "does not lower the criterion" if change >= 0.0 else
                   "another candidate lowers it more")
            decisions.append(_decision("forward", _joined(step), sc, change, n_eff, False,
                                       why))
        if best is None or not best[0] < 0.0:
            break
        change, step, sc = best
        decisions.append(_decision("forward", _joined(step), sc, change, n_eff, True,
                                   "lowers the criterion most"))
        say(f"  -> {_joined(step)} joins")
        current = sc
        added += [c.name for c in step]
        pool = [c for c in pool if all(c is not s for s in step)]
    # backward, once: what a later candidate made redundant leaves
    for name in list(added) if len(added) >= 2 else []:
        if name not in current.structure:
            continue
        needed_by = [c.name for c in candidates
                     if c.name in current.structure and name in c.requires]
        if needed_by:
            continue
        n_eff = effective_samples(current.residual, settings.max_lag_share)
        trial = tuple(e for e in current.structure if e != name)
        sc = score(trial, current)
        scores["+".join(sc.structure)] = sc.rms
        change = criterion_change(sc.sse, current.sse, sc.k, current.k, n_eff,
                                  settings.penalty)
        leaves = sc.violation is None and change <= 0.0
        decisions.append(_decision("backward", name, sc, change, n_eff, leaves,
                                   "redundant once the others are in" if leaves else
                                   "still lowers the criterion"))
        say(f"  - {name}: held-out rms without it {describe(sc.rms)}, criterion "
            f"{change:+.3g}{': leaves' if leaves else ''}")
        if leaves:
            current = sc
    return Selection(current, decisions, scores)
