"""Forward selection of effects, judged on held-out data.

Each step tries every candidate effect that is not yet in the model, scores it by the error it
removes on *held-out* samples (two folds of interleaved time blocks: fit on one, score on the
other, both ways), adds the best one if the gain is significant and the effect has a physical
size, refits every parameter with it (grey box) and repeats.

* With a measured effort, force effects are judged on the effort of the inverse dynamics
  (linear least squares: fast and well conditioned); output effects (backlash, thermal drift)
  on the free-run position, since they do not change the effort.
* Without an effort, every effect is judged on the free-run position. A linearised screen
  (finite-difference columns of each candidate at a probe size or at a start found by the
  inverse dynamics of the controller's virtual effort, next to the Jacobian of the current
  parameters) ranks the candidates; the best few - and Coulomb friction while it is missing,
  cogging (from several periods of the residual's spectrum against position), and the
  runners-up of the previous step - are then fitted for real (nonlinear output error) on
  each fold. The loop gains are hardly identifiable from the position alone (with
  feedforward the reference is tracked whatever they are), so while a candidate is judged
  they may only move by a factor ``settings.loop_box`` and the integral action may not vanish: an
  effect must explain the residual through the loop as it is, not by changing the loop (the
  known ways to mistake friction for backlash or a slow loop for thermal drift). Before the
  first effect, the fits also start from the loop identified together with a Coulomb force
  (:func:`fricbench.sysid.diagnose.baselines.friction_aware_loop`).

Significance: with ``rho`` the ratio of held-out squared errors with and without the
candidate, a candidate with ``p`` parameters must reach ``-ln(rho) >= min_gain +
gain_per_param * p``; among those that do, the one with the largest gain *per parameter* wins
(the simplest sufficient explanation first). The search stops when nothing passes; a residual
at the noise floor of a free-run prediction does not stop it (a friction effect needs no size
against that floor, an effect that is not friction must stand above it:
:func:`min_position_size`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from scipy.stats import binom

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.controllers import CascadeController
from fricbench.sysid.diagnose.criterion import block_consistency, false_detection_rate
from fricbench.sysid.diagnose.effects import (
    Effect,
    default_candidates,
    describe_parameters,
    excluded,
    get_effect,
)
from fricbench.sysid.diagnose.equation_error import loop_by_equation_error
from fricbench.sysid.diagnose.leastsq import matvec, solve_ls, sumsq
from fricbench.sysid.diagnose.models import (
    Bounds,
    GreyBox,
    InverseDynamics,
    NoStartError,
    Param,
    PositionFit,
    PositionFitResult,
    cascade_effort,
    position_params,
    prediction_floor,
    race_fits,
    run_concurrently,
    simulate_models,
    simulate_position,
)
from fricbench.sysid.diagnose.prepared import Prepared
from fricbench.sysid.diagnose.settings import DiagnoseSettings, defaults
from fricbench.sysid.diagnose.signals import fold_blocks
from fricbench.sysid.io import MIN_STARTS

__all__ = ["SearchSettings", "Step", "CandidateScore", "SearchResult", "forward_selection",
           "effects_tried", "min_position_size", "required_gain"]


def effects_tried(settings: DiagnoseSettings) -> tuple[str, ...]:
    """The effects the closed-loop search tries: ``settings.candidates``, or the library as
    registered now but for the effects tried only when asked for
    (:attr:`Effect.tried_by_default`)."""
    if settings.candidates is not None:
        return settings.candidates
    return default_candidates()


def min_position_size(settings: DiagnoseSettings, effect: str) -> float:
    """Smallest rms position contribution of ``effect``, in noise floors.

    0 for friction: the suspect of every axis is judged by its held-out cut and the
    detection rule alone (its size within ``settings.detection_sd`` standard deviations of
    zero is "not detected"), not by a size against a floor that is itself a bound (a
    velocity-loop drive's friction can move its position by less than the floor's three
    sensor noises and still cut the held-out error by half). An effect that is not friction
    must stand above what the verdict calls "at the floor" (``settings.floor_factor`` floors),
    else a flexible effect that cuts the held-out error is fitting what the loop model misses.
    """
    return 0.0 if get_effect(effect).friction else settings.floor_factor


def required_gain(settings: DiagnoseSettings, n_params: int, effect: str | None = None,
                  judged_on: str = "effort") -> float:
    """Required ``-ln`` held-out ratio for an effect with ``n_params`` parameters.

    A non-friction ``effect`` judged on the position needs ``settings.min_gain_position_other``
    instead of ``settings.min_gain``.
    """
    base = settings.min_gain
    if (effect is not None and judged_on.startswith("position")
            and not get_effect(effect).friction):
        base = max(base, settings.min_gain_position_other)
    return base + settings.gain_per_param * n_params



SearchSettings = DiagnoseSettings
"""The search's thresholds, now fields of :class:`DiagnoseSettings` (the name is kept for code
that builds ``SearchSettings(max_steps=...)``)."""


@dataclass
class CandidateScore:
    """How one candidate fared at one step."""

    effect: str
    n_params: int
    heldout_ratio: float
    judged_on: str
    size: float = float("nan")
    size_ok: bool = True
    note: str = ""

    @property
    def gain(self) -> float:
        """``-ln`` of the held-out error ratio."""
        return -math.log(max(self.heldout_ratio, 1e-300))

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        out: dict[str, object] = {"effect": self.effect, "n_params": self.n_params}
        if math.isfinite(self.heldout_ratio):
            out["heldout_error_ratio"] = self.heldout_ratio
            out["heldout_gain_pct"] = 100.0 * (1.0 - self.heldout_ratio)
        else:
            # its held-out fit diverged: a rejected candidate, said so, never an inf
            out["diverged"] = True
        out["judged_on"] = self.judged_on
        if math.isfinite(self.size):
            # a candidate ranked but not fitted has no size: the key is left out, not null
            out["size"] = self.size
        out["size_ok"] = self.size_ok
        out["note"] = self.note
        return out


@dataclass
class Step:
    """One step of the search: the model after adding ``effect`` (None: the linear model).

    ``candidates`` are the scores of the round that added ``effect``; ``rejected`` those of the
    round after it when that round added nothing (the last step's: why the search stopped).
    """

    effect: str | None
    model: GreyBox
    y: np.ndarray = field(repr=False)
    position_rms: float
    position_max: float
    effort_relerr_pct: float | None
    candidates: list[CandidateScore] = field(default_factory=list)
    heldout_ratio: float | None = None
    rejected: list[CandidateScore] = field(default_factory=list)


@dataclass
class SearchResult:
    """All steps and why the search stopped."""

    steps: list[Step]
    stop_reason: str
    floor: float
    elapsed_s: float
    warnings: list[str] = field(default_factory=list)

    @property
    def final(self) -> Step:
        """The last accepted step."""
        return self.steps[-1]


# -- helpers --------------------------------------------------------------------------------------
def _rms(r: np.ndarray) -> float:
    return float(np.sqrt(sumsq(r) / r.shape[0])) if np.all(np.isfinite(r)) else float("inf")


def _length(prep: Prepared, value: float) -> str:
    """A position figure (SI) in the unit the log was in (deg stays deg, mm stays mm)."""
    unit = prep.run.logged_unit
    return f"{value * unit.per_si:.4g} {unit.display}"


def _n_params(effect: str, effects: tuple[str, ...]) -> int:
    return len(get_effect(effect).free(effects))


def _shown_by(effect: Effect, prep: Prepared) -> bool:
    """Whether the motion of ``prep``'s run can show ``effect`` at all: its reversals, or its
    starts from rest for a friction level (:attr:`Effect.shown_at_rests`)."""
    if not effect.needs_reversals or prep.run.n_reversals > 0:
        return True
    return effect.shown_at_rests and prep.run.n_starts >= MIN_STARTS


def _available(model: GreyBox, prep: Prepared, settings: DiagnoseSettings) -> list[str]:
    out = []
    for name in effects_tried(settings):
        effect = get_effect(name)
        if name in model.effects:
            continue
        if any(r not in model.effects for r in effect.requires):
            continue
        if excluded(name, model.effects):
            continue  # the same term in another shape is in
        if not _shown_by(effect, prep):
            continue
        if not effect.available(prep):
            continue
        out.append(name)
    return out


def _init_effect(model: GreyBox, name: str, prep: Prepared, b: Bounds) -> GreyBox:
    """Model with effect ``name`` switched on at neutral values (fit starts)."""
    p = get_effect(name).switched_on(model.plant, prep)
    return model.copy(plant=p, effects=model.effects + (name,))


def _free_positions(models: Sequence[GreyBox], prep: Prepared, w: np.ndarray | None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`simulate_models` for the effects' starts and evidence, which read the positions
    only (the effort comes back NaN where a kept run is handed back without it)."""
    return simulate_models(models, prep, w, effort=False)


def _position_sse(y: np.ndarray, prep: Prepared, mask: np.ndarray) -> float:
    r = (prep.x - y)[mask]
    return sumsq(r) if np.all(np.isfinite(r)) else float("inf")


def _blocks(prep: Prepared) -> list[tuple[int, int]]:
    """The held-out blocks of the run as sample ranges, fold 0's first (:func:`fold_blocks`)."""
    return fold_blocks(prep.folds)


def _block_sse(y: np.ndarray, prep: Prepared, fold: int, x: np.ndarray | None = None
               ) -> np.ndarray:
    """Squared position error of each block of ``fold``, in time order (inf where ``y`` is
    not finite); of the measured ``x`` (default: the position ``prep.x``)."""
    r = (prep.x if x is None else x) - y
    out = [sumsq(r[a:z]) if np.all(np.isfinite(r[a:z])) else math.inf
           for a, z in _blocks(prep) if prep.folds[a] == fold]
    return np.asarray(out, dtype=float)


def block_left_out(cand: np.ndarray, base: np.ndarray) -> int | None:
    """The held-out block left out of a candidate's judgement, or None (judged on every block).

    A candidate is judged on the ratio of its held-out squared error to the base model's,
    summed over the blocks, except when one block alone goes against all the others: a run
    with a single event of its kind (one rapid move, ten times faster than the rest, whose
    deceleration clips the drive) puts it in one block, and a fold fit that never saw such an
    event may predict it far worse although it predicts the rest of the run far better (a
    viscous term fitted on slow motion alone, extrapolated). When the candidate predicts so
    many of the other blocks better that chance alone would give as many with a probability
    of at most ``2 Phi(-settings.detection_sd)`` (a one-sided sign test at the detection
    rule's false-detection rate, 4.6 %: 14 of 19 other blocks, the whole run's 20 blocks less
    one) and the block where it loses most at least ``settings.one_block_worse`` times worse,
    that block is left out of both sums. The winner is still refitted on every sample and
    must keep its cut there, and its note in the report names the block and gives the ratio
    with it.

    Parameters
    ----------
    cand, base : ndarray
        Squared held-out error per block of the candidate and of the base model (the same
        blocks, in the same order).
    """
    if cand.size < 4 or not (np.all(np.isfinite(cand)) and np.all(np.isfinite(base))):
        return None
    diff = cand - base
    j = int(np.argmax(diff))
    if not (cand[j] >= defaults().one_block_worse * base[j] and diff[j] > 0.0):
        return None
    others = np.delete(diff, j)
    better = int(np.sum(others < 0.0))
    # P(at least `better` of the others better | each a fair coin)
    chance = float(binom.sf(better - 1, others.size, 0.5))
    return j if chance <= false_detection_rate(defaults().detection_sd) else None


def _judged_ratio(total_c: float, total_b: float, cand: np.ndarray, base: np.ndarray
                  ) -> tuple[float, int | None, str]:
    """The held-out ratio a candidate is judged on (:func:`block_left_out`), the block left
    out and a note saying so (empty when none is)."""
    j = block_left_out(cand, base)
    ratio = total_c / max(total_b, 1e-300)
    if j is None:
        return ratio, None, ""
    judged = (total_c - cand[j]) / max(total_b - base[j], 1e-300)
    return judged, j, (f"judged without held-out block {j + 1} of {cand.size}, which it alone "
                       f"predicts worse (x{cand[j] / max(base[j], 1e-300):.3g}); with it "
                       f"x{ratio:.3f}")


def _check_consistency(sc: CandidateScore, cand: np.ndarray, base: np.ndarray,
                       left_out: int | None, settings: DiagnoseSettings) -> None:
    """Reject (``sc.size_ok = False``, said in its note) an effect that is not friction, judged
    on the free-run position, whose held-out cut is not consistent over the run's blocks
    (:func:`~fricbench.sysid.diagnose.criterion.block_consistency` above the detection rule's
    level ``2 Phi(-settings.detection_sd)``, 4.6 %): a flexible effect trading blocks absorbs
    a misfit of the loop model. The level is the detection rule's false-detection rate (a size
    within ``detection_sd`` standard deviations of zero on either side), so one rate governs
    every "is it there" decision. Friction is the suspect of every axis and is judged by its
    cut alone."""
    if get_effect(sc.effect).friction or not sc.judged_on.startswith("position"):
        return
    p = block_consistency(cand, base, left_out)
    level = false_detection_rate(settings.detection_sd)
    if p is None or p <= level:
        return
    sc.size_ok = False
    sc.note += ("; " if sc.note else "") + (
        f"rejected: its held-out cut is not consistent over the run's blocks (Wilcoxon "
        f"signed-rank p = {p:.3g} > {level:.3g})")


# -- with an effort -------------------------------------------------------------------------------
def _output_fit(model: GreyBox, prep: Prepared, b: Bounds, w: np.ndarray | None,
                mask: np.ndarray | None, max_iter: int = 12) -> PositionFitResult:
    outputs = [e for e in model.effects if get_effect(e).kind == "output"]
    # an effect that changes the dynamics (compliance) refits the mass and damping the rigid
    # inverse dynamics found: they are biased by it
    m = float(model.plant[CL.I_M])
    dynamic = any(get_effect(e).refits_mass for e in outputs) and m > 0.0 and math.isfinite(m)
    params = position_params(model, b, controller=False, effects=outputs, damping=dynamic)
    if dynamic:
        params.append(Param(CL.I_M, True, 0.5 * m, 2.0 * m, 1.0))
    fit = PositionFit(prep, params, mask, w)
    return fit.run(model, max_iter=max_iter)


def _output_candidate(model: GreyBox, name: str, prep: Prepared, b: Bounds,
                      w: np.ndarray | None, y: np.ndarray
                      ) -> tuple[float, list[GreyBox], np.ndarray, np.ndarray]:
    """Held-out position ratio of an output effect added to a fixed model, its fold fits, and
    the squared held-out position error per block with and without it."""
    base_sse = 0.0
    cand_sse = 0.0
    fits = []
    cand_blocks: list[np.ndarray] = []
    base_blocks: list[np.ndarray] = []
    # a load encoder: its held-out error joins the motor's, as in the fit (PositionFit); the
    # deflection of a coupling shows there, where the loop does not hold it down
    base_load = None if prep.x_load is None else _load_positions([model], prep, w)[0]
    for k in (0, 1):
        train = prep.folds != k
        m = _init_effect(model, name, prep, b)
        m = get_effect(name).output_start(m, prep, b, w, y, train, _free_positions)
        res = _output_fit(m, prep, b, w, train)
        fits.append(res.model)
        base_sse += _position_sse(y, prep, ~train)
        cand_sse += _position_sse(res.y, prep, ~train)
        cand_blocks.append(_block_sse(res.y, prep, k))
        base_blocks.append(_block_sse(y, prep, k))
        if base_load is not None and prep.x_load is not None:
            cand_load = _load_positions([res.model], prep, w)[0]
            base_sse += _load_sse(base_load, prep, ~train)
            cand_sse += _load_sse(cand_load, prep, ~train)
            # the blocks judge what the sums judge: both encoders
            cand_blocks[-1] = cand_blocks[-1] + _block_sse(cand_load, prep, k, prep.x_load)
            base_blocks[-1] = base_blocks[-1] + _block_sse(base_load, prep, k, prep.x_load)
    return (cand_sse / max(base_sse, 1e-300), fits, np.concatenate(cand_blocks),
            np.concatenate(base_blocks))


def _load_positions(models: Sequence[GreyBox], prep: Prepared, w: np.ndarray | None
                    ) -> np.ndarray:
    """Free-run positions of the load encoder (``prep.x_load``) of ``models``."""
    loads = np.empty((len(models), prep.n))
    simulate_models(models, prep, w, other=loads, effort=False)
    return loads


def _load_sse(y_load: np.ndarray, prep: Prepared, mask: np.ndarray) -> float:
    if prep.x_load is None:
        return 0.0
    r = (prep.x_load - y_load)[mask]
    return sumsq(r) if np.all(np.isfinite(r)) else float("inf")


def _effect_position_size(model: GreyBox, name: str, prep: Prepared, w: np.ndarray | None,
                          y: np.ndarray) -> float:
    y0, _ = simulate_position(model.without(name), prep, w)
    return _rms(y - y0)


def _kept_in_refit(sc: CandidateScore, why: str | None, size: float, min_size: float,
                   kept: float, need: float, floor: float, warnings: list[str]) -> bool:
    """Whether a winner's refit on all samples keeps it: not an artefact (``why`` is None), at
    least ``min_size`` noise floors, and the error cut ``kept <= need``. Else the score is
    marked rejected with the reason (an artefact's is also a warning)."""
    if why is None and size >= min_size * floor and kept <= need:
        return True
    sc.size_ok = False
    if why is not None:
        sc.note += f"; rejected: {why}"
        warnings.append(f"rejected {why}")
    else:
        sc.note += (f"; vanished in the refit on all samples (size {size / floor:.2f}, "
                    f"error x{kept:.3f})")
    return False


def _force_params(model: GreyBox, b: Bounds, effects: Sequence[str]) -> list:
    """The free parameters of ``effects`` (force effects), the loop and mass fixed."""
    return position_params(model, b, controller=False, effects=list(effects), damping=False)


def _heldout_effort_sse(idim: InverseDynamics, fits: dict[int, PositionFitResult]) -> float:
    """Squared effort error of fold fits on the sliding rows of the fold each left out."""
    prep = idim.prep
    total = 0.0
    for k, res in fits.items():
        rows = (prep.folds_dec == k) & prep.sliding_dec
        total += sumsq((idim.u_dec - idim.predict(res.model.plant))[rows])
    return total


def _probe_starts(m: GreyBox, name: str, prep: Prepared, b: Bounds, y: np.ndarray
                  ) -> list[GreyBox]:
    """Starts of candidate ``name`` at each of its probes (:meth:`Effect.probes`, the shapes
    and sizes the position screen tries), every probed value set at once."""
    m0 = _init_effect(m, name, prep, b)
    out = []
    for changes, fixed in get_effect(name).probes(m0.plant, m0.effects, prep, b, y):
        q = m0.plant.copy()
        for i, v in {**fixed, **changes}.items():
            q[i] = v
        out.append(m0.copy(plant=_physical(q, name, b, list(changes))))
    return out


def _best_start(starts: Sequence[GreyBox], prep: Prepared, w: np.ndarray | None,
                mask: np.ndarray) -> GreyBox:
    """The start whose free run leaves the least squared position error on ``mask`` (the
    first when none stays finite)."""
    if len(starts) == 1:
        return starts[0]
    ys, _, _ = _free_positions(starts, prep, w)
    sse = [_position_sse(yy, prep, mask) for yy in ys]
    return starts[int(np.argmin(sse))] if np.any(np.isfinite(sse)) else starts[0]


def _force_by_position(m: GreyBox, y: np.ndarray, prep: Prepared, idim: InverseDynamics,
                       b: Bounds, settings: DiagnoseSettings, w: np.ndarray | None,
                       floor: float, log: Callable[[str], None], warnings: list[str]
                       ) -> tuple[list[CandidateScore],
                                  tuple[CandidateScore, GreyBox, np.ndarray] | None]:
    """One step of force effects judged on the held-out free-run position (with an effort).

    A logged effort can be too noisy to show a force the position shows clearly: a command
    computed from a finely quantised encoder through a fast velocity loop is mostly its noise,
    while the loop integrates a small change of the friction level along the stroke into a
    position error many noise floors high. Each candidate starts from its inverse-dynamics
    fit on the training fold; its parameters and those of the force effects already in the
    model are fitted to the training fold's position (the law and the mass fixed) and judged
    on the other fold against the model without it, refitted the same way (so a refitted
    friction level alone is no gain). Returns the scores and, when one wins, ``(score,
    model, y)`` as :func:`_search_with_effort` accepts it. A candidate that makes the held-out
    effort error worse by more than ``settings.tolerance`` is rejected.
    """
    forces = [e for e in m.effects if get_effect(e).kind == "force"]
    base_fits = {}
    base_heldout = 0.0
    for k in (0, 1):
        train = prep.folds != k
        res = PositionFit(prep, _force_params(m, b, forces), train, w).run(m, max_iter=8)
        base_fits[k] = res
        base_heldout += _position_sse(res.y, prep, ~train)
    scores: list[CandidateScore] = []
    fits: dict[str, dict[int, PositionFitResult]] = {}
    for name in _available(m, prep, settings):
        if get_effect(name).kind != "force":
            continue
        effects = m.effects + (name,)
        try:
            _, fold_rows = idim.cv_sse(effects, _init_effect(m, name, prep, b).plant, new=name)
        except NoStartError as exc:
            log(f"    {name:28s} not fitted: {exc}")
            continue
        heldout = 0.0
        fk: dict[int, PositionFitResult] = {}
        probed = _probe_starts(m, name, prep, b, y)
        for k in (0, 1):
            train = prep.folds != k
            start = _best_start([m.copy(plant=fold_rows[k], effects=effects), *probed], prep,
                                w, train)
            res = PositionFit(prep, _force_params(start, b, [*forces, name]), train, w).run(
                start, max_iter=8)
            fk[k] = res
            heldout += _position_sse(res.y, prep, ~train)
        rho = heldout / max(base_heldout, 1e-300)
        if not math.isfinite(rho):
            continue
        effort_ratio = _heldout_effort_sse(idim, fk) / max(
            _heldout_effort_sse(idim, base_fits), 1e-300)
        size = min(_effect_position_size(fk[k].model, name, prep, w, fk[k].y) for k in (0, 1))
        sc = CandidateScore(name, _n_params(name, effects), rho, "position", size / floor,
                            size >= min_position_size(settings, name) * floor,
                            "judged on the position: the effort shows no more")
        if effort_ratio > 1.0 + settings.tolerance:
            # the measured effort contradicts it: a force the effort does not carry stands in
            # for a mismatch of the loop (on a hobby motor's step run, Coulomb, Stribeck and
            # position-dependent friction fitted this way cut the training position error 2x
            # and made the other run's prediction worse)
            sc.size_ok = False
            sc.note += (f"; rejected: it makes the held-out effort error worse "
                        f"(x{effort_ratio:.3f})")
        scores.append(sc)
        fits[name] = fk
        log(f"    {name:28s} held-out position error x{rho:.3f} ({sc.n_params} par), effort "
            f"x{effort_ratio:.3f}{'' if sc.size_ok else ' rejected'} (force judged on the "
            "position)")
    pool = list(scores)
    # the model without the winner refitted on all samples, from the fold fit its start came
    # from: once per fold, whichever winners try it
    base_full: dict[int, PositionFitResult] = {}
    while True:
        winner = _pick(pool, settings)
        if winner is None:
            return scores, None
        pool = [s for s in pool if s is not winner]
        fk = fits[winner.effect]
        k_best = min(fk, key=lambda k: fk[k].cost)
        start = fk[k_best].model
        full = PositionFit(prep, _force_params(start, b, [*forces, winner.effect]), None,
                           w).run(start, max_iter=12)
        if k_best not in base_full:
            base_full[k_best] = PositionFit(prep, _force_params(m, b, forces), None, w).run(
                base_fits[k_best].model, max_iter=12)
        size = _effect_position_size(full.model, winner.effect, prep, w, full.y)
        why = artefact(full.model, winner.effect, prep, b, w)
        if why is None and not np.all(np.isfinite(full.y)):
            why = f"{winner.effect}: the loop with it diverges in a free run of the training run"
        kept = full.cost / max(base_full[k_best].cost, 1e-300)
        need = math.exp(-required_gain(settings, winner.n_params, winner.effect, winner.judged_on))
        if _kept_in_refit(winner, why, size, min_position_size(settings, winner.effect), kept, need,
                          floor, warnings):
            return scores, (winner, full.model, full.y)
        log(f"    {winner.effect} rejected: {winner.note}")


def _effort_step_score(m: GreyBox, name: str, y: np.ndarray, prep: Prepared,
                       idim: InverseDynamics, b: Bounds, w: np.ndarray | None,
                       settings: DiagnoseSettings, floor: float, u_rms: float,
                       base: tuple[float, np.ndarray], log: Callable[[str], None]
                       ) -> tuple[CandidateScore, GreyBox] | None:
    """One candidate of a step of :func:`_search_with_effort` added to ``m`` (whose free-run
    position is ``y``; ``base`` its held-out effort errors, total and per block): its score
    and the model it proposes, or None when it has no start. A force effect is judged on the
    held-out effort, an output effect on the held-out free-run position (three fits)."""
    effects = m.effects + (name,)
    n_par = _n_params(name, effects)
    if get_effect(name).kind == "force":
        p0 = _init_effect(m, name, prep, b).plant
        try:
            cv, cv_blocks, _ = idim.cv_blocks(effects, p0, new=name)
            p_all = idim.fit(effects, p0, new=name)
        except NoStartError as exc:
            log(f"    {name:28s} not fitted: {exc}")
            return None
        ratio, _, block_note = _judged_ratio(cv, base[0], cv_blocks, base[1])
        force = idim.predict(p_all) - idim.predict(_zero_effect(p_all, name, effects))
        # its size is the rms force relative to the rms effort, reported, not a threshold: a
        # force effect below 0.5 % of the effort was "too small" (min_force_share, set by hand
        # with the first search), retired when both held-out sets gave every row as with it;
        # the held-out cut, the blocks' consistency and the detection rule judge it
        share = _rms(force) / max(u_rms, 1e-300)
        sc = CandidateScore(name, n_par, ratio, "effort", share, not math.isnan(share),
                            block_note)
        proposal = m.copy(plant=p_all, effects=effects)
    else:
        ratio, _, cand_blocks, base_pos_blocks = _output_candidate(m, name, prep, b, w, y)
        fitted = _output_fit(_start_output(m, name, prep, b, w, y), prep, b, w, None)
        proposal = fitted.model
        size = _effect_position_size(proposal, name, prep, w, fitted.y)
        sc = CandidateScore(name, n_par, ratio, "position", size / floor,
                            size >= min_position_size(settings, name) * floor)
        _check_consistency(sc, cand_blocks, base_pos_blocks, None, settings)
    log(f"    {name:28s} held-out {sc.judged_on} error x{sc.heldout_ratio:.3f} ({n_par} par)"
        f"{'' if sc.size_ok or 'rejected' in sc.note else ' too small'}"
        f"{f' ({sc.note})' if sc.note else ''}")
    return sc, proposal


def _step_floor(m: GreyBox, steps: Sequence[Step], prep: Prepared, w: np.ndarray | None,
                floor_linear: float, lower: float) -> float:
    """The noise floor a search step judges with: the lower of the free-run floors of ``m``
    (the model found so far) and of the linear model (``floor_linear``: a poorly damped model
    exaggerates the noise it is fed), never below ``lower``. Both searches take it so; at the
    first step ``m`` is the linear model, whose floor is not simulated again."""
    own = floor_linear if len(steps) == 1 else prediction_floor(m, prep, w)
    return max(min(own, floor_linear), lower)


def _search_with_effort(model: GreyBox, prep: Prepared, idim: InverseDynamics, b: Bounds,
                        settings: DiagnoseSettings, w: np.ndarray | None,
                        log: Callable[[str], None], warnings: list[str]
                        ) -> tuple[list[Step], str, float]:
    y, _ = simulate_position(model, prep, w)
    steps = [Step(None, model, y, _rms(prep.x - y), float(np.max(np.abs(prep.x - y))),
                  idim.relerr(model.plant))]
    u_rms = float(np.sqrt(np.mean(idim.u_dec**2)))
    # never below the sensor's own floor (never zero: NoiseFloor.rms > 0), so every ratio to
    # it is finite
    floor_linear = max(prediction_floor(model, prep, w), prep.noise.rms)
    floor = floor_linear
    reason = f"reached the maximum of {settings.max_steps} effects"
    by_position = False
    accepted: tuple[CandidateScore, GreyBox, np.ndarray] | None
    scores: list[CandidateScore]
    for _ in range(settings.max_steps):
        cur = steps[-1]
        m = cur.model
        # the floor of the model found so far (a frictionless loop fed the noise can wander far
        # more than the axis: a PID at its drive's limit, 0.80 mrad against 22 urad with the
        # Coulomb friction found, the run's true floor 6.2 urad)
        floor = _step_floor(m, steps, prep, w, floor_linear, prep.noise.rms)
        judged_on_position = by_position
        if by_position:
            scores, accepted = _force_by_position(m, cur.y, prep, idim, b, settings, w,
                                                  floor, log, warnings)
        else:
            base_cv, base_blocks, _ = idim.cv_blocks(m.effects, m.plant)
            base = (base_cv, base_blocks)
            names = list(_available(m, prep, settings))
            scored: dict[str, CandidateScore] = {}
            proposals: dict[str, GreyBox] = {}

            # force effects first: an output effect cannot change the effort, and while a force
            # effect is missing the position residual it leaves can look like an output effect.
            # A winner must not be an artefact; else the next candidate is tried. The free-run
            # position is checked on the final model (:func:`_position_prune`): one effect alone
            # may worsen it while the pair it belongs to improves it (Coulomb friction without
            # the cogging that dominates the effort). The candidates are scored in two batches:
            # the force effects, then, only when none of them is taken, the output effects
            # (three fits each on the free-run position): a step a force effect wins never
            # looks at them, and its report lists the force effects.
            batches = [[n for n in names if get_effect(n).kind == "force"],
                       [n for n in names if get_effect(n).kind != "force"]]
            accepted = None
            tried: set[str] = set()
            while accepted is None:
                pool = [scored[n] for n in names if n in scored and n not in tried]
                winner = _pick([s for s in pool if s.judged_on == "effort"], settings)
                if winner is None and batches:
                    if len(batches) == 1 and batches[0]:
                        log("    no force effect taken: the output effects are scored")
                    for name in batches.pop(0):
                        out = _effort_step_score(m, name, cur.y, prep, idim, b, w, settings,
                                                 floor, u_rms, base, log)
                        if out is not None:
                            scored[name], proposals[name] = out
                    continue
                if winner is None:
                    winner = _pick(pool, settings)
                if winner is None:
                    break
                tried.add(winner.effect)
                new = proposals[winner.effect]
                if get_effect(winner.effect).kind == "force" and any(
                        get_effect(e).kind == "output" for e in new.effects):
                    new = _output_fit(new, prep, b, w, None).model
                y_new, _ = simulate_position(new, prep, w)
                why = artefact(new, winner.effect, prep, b, w)
                if why is None and not np.all(np.isfinite(y_new)):
                    # a model whose loop diverges is rejected, not reported
                    why = (f"{winner.effect}: the loop with it diverges in a free run of the "
                           "training run")
                if why is not None:
                    winner.size_ok = False
                    winner.note = (winner.note + "; " if winner.note else "") + "rejected: " + why
                    warnings.append(f"rejected {why}")
                    log(f"    rejected {why}")
                    continue
                accepted = (winner, new, y_new)
            scores = [scored[n] for n in names if n in scored]
            if accepted is None and cur.position_rms > settings.floor_factor * floor:
                # the effort shows no more force, the position still does: judge the force
                # effects on it from here on
                log("  the effort shows no more: force effects judged on the free-run position")
                by_position = True
                p_scores, accepted = _force_by_position(m, cur.y, prep, idim, b, settings, w,
                                                        floor, log, warnings)
                scores = scores + p_scores
        if accepted is None:
            reason = ("no candidate improves the held-out position error significantly"
                      if judged_on_position else
                      "no candidate improves the held-out error significantly")
            cur.rejected = scores
            break
        winner, new, y_new = accepted
        step = Step(winner.effect, new, y_new, _rms(prep.x - y_new),
                    float(np.max(np.abs(prep.x - y_new))), idim.relerr(new.plant), scores,
                    winner.heldout_ratio)
        steps.append(step)
        if judged_on_position:
            log(f"  + {winner.effect} (judged on the position): position rms "
                f"{_length(prep, step.position_rms)}")
        else:
            log(f"  + {winner.effect}: effort relerr {step.effort_relerr_pct:.3f} %, position "
                f"rms {_length(prep, step.position_rms)}")
    return steps, reason, floor


def _refit_without(model: GreyBox, name: str, idim: InverseDynamics) -> GreyBox:
    """``model`` without effect ``name``, its force terms refitted to the effort."""
    m = model.without(name)
    if get_effect(name).kind == "force":
        m = m.copy(plant=idim.fit(m.effects, m.plant))
    return m


def _position_prune(model: GreyBox, prep: Prepared, idim: InverseDynamics,
                    w: np.ndarray | None, log: Callable[[str], None]
                    ) -> list[tuple[str, float, float]]:
    """Effects of ``model`` that make its free-run position worse, removed one at a time.

    The effort search never fits the free-run position, so it is held out from it. Each
    round removes the effect whose removal (the force terms refitted without it) lowers the
    free-run rms the most, while the model with it is worse by more than
    ``settings.tolerance``. Returns ``(effect, rms with, rms without)`` per removal.
    """
    out: list[tuple[str, float, float]] = []
    y, _ = simulate_position(model, prep, w)
    rms = _rms(prep.x - y)
    while model.effects:
        trials = [_refit_without(model, e, idim) for e in model.effects]
        ys = simulate_models(trials, prep, w)[0]
        rms_without = [_rms(prep.x - yy) for yy in ys]
        k = int(np.argmin(rms_without))
        if not rms > (1.0 + defaults().tolerance) * rms_without[k]:
            break
        out.append((model.effects[k], rms, rms_without[k]))
        log(f"    {model.effects[k]} makes the free-run position worse: "
            f"{_length(prep, rms)} rms with it, {_length(prep, rms_without[k])} without it")
        model, rms = trials[k], rms_without[k]
    return out


def _zero_effect(p: np.ndarray, name: str, effects: tuple[str, ...]) -> np.ndarray:
    return get_effect(name).zeroed(p, effects)


def _start_output(model: GreyBox, name: str, prep: Prepared, b: Bounds, w: np.ndarray | None,
                  y: np.ndarray) -> GreyBox:
    m = _init_effect(model, name, prep, b)
    allm = np.ones(prep.n, dtype=bool)
    return get_effect(name).output_start(m, prep, b, w, y, allm, _free_positions)


def artefact(model: GreyBox, name: str, prep: Prepared, b: Bounds,
             w: np.ndarray | None = None) -> str | None:
    """Why the fitted effect ``name`` of ``model`` is a sensor or fit artefact, or None.

    * a spatial period that the run cannot tell from a small multiple of the sensor quantum
      (the staircase of a coarse sensor leaves a residual with that period): two periods
      ``p`` and ``p'`` differ by one cycle over the stroke ``L`` when ``|p / p' - 1| = p /
      L``, the finest a run of that stroke resolves (Rayleigh's criterion, spatial);
    * the spatial period of a periodic term (:attr:`Effect.periodic`) longer than the stroke
      (a level change, not a period);
    * a spatial period the run cannot tell (as above) from another effect's in the model (a
      friction varying along the stroke at the cogging's period is what a cogging that is not
      a pure sine leaves, not a second effect);
    * a shape parameter (a period, a time constant, a Stribeck velocity) that ended on a
      bound of its physical range (the optimum lies outside it: the effect stands in for
      something else), and so does a size whose range is physical
      (:attr:`Effect.physical_sizes`, a backlash's gap). Other sizes are not checked: their
      bounds are a multiple of the run's force scale, not a physical limit, and a vanished
      size is rejected by the size test;
    * what the effect's own :meth:`Effect.evidence` finds missing in the run (``w``: the
      injected input of the free runs, as in :func:`simulate_position`).
    """
    effect = get_effect(name)
    p = model.plant
    if effect.period_parameter is not None:
        per = float(p[effect.period_parameter])
        q = prep.noise.quantum
        # the relative resolution of a period over the run's stroke: one cycle more or less
        resolution = per / prep.stroke if prep.stroke > 0.0 else math.inf
        for k in defaults().quantum_multiples:
            if q > 0.0 and abs(per / (k * q) - 1.0) <= resolution:
                times = "" if k == 1 else f"{k} x "
                return (f"{name}: its period {per:.4g} is {times}the sensor quantum "
                        f"{q:.4g}: the sensor's staircase, not the axis")
        if effect.periodic and per > prep.stroke:
            return (f"{name}: its period {per:.4g} is longer than the stroke {prep.stroke:.4g}: "
                    "a level change, not a period")
        for other in model.effects:
            o = get_effect(other)
            if other == name or o.period_parameter is None:
                continue
            per_o = float(p[o.period_parameter])
            if per_o > 0.0 and abs(per / per_o - 1.0) <= resolution:
                return (f"{name}: its period {per:.4g} is that of {other} ({per_o:.4g}): the "
                        f"same periodic term twice (the residual of {other}'s shape), not a "
                        "second effect")
    for i in effect.free(model.effects):
        if i not in effect.shape_parameters and i not in effect.physical_sizes:
            continue
        v = float(p[i])
        par = effect.bounds(i, v, b)
        side = par.bound_hit(v)
        if side is not None:
            at = par.hi if side == "upper" else par.lo
            return (f"{name}: its parameter {CL.PLANT_NAMES[i]} = {v:.4g} ended on its {side} "
                    f"bound {at:.4g}: the optimum lies outside the physical range")
    return effect.evidence(model, prep, w, _free_positions)


def _pick(scores: list[CandidateScore], settings: DiagnoseSettings) -> CandidateScore | None:
    ok = [s for s in scores if s.size_ok
          and s.gain >= required_gain(settings, s.n_params, s.effect, s.judged_on)]
    if not ok:
        return None
    return max(ok, key=lambda s: s.gain / s.n_params)


# -- without an effort ----------------------------------------------------------------------------
@dataclass
class _Probe:
    """Finite-difference columns of one candidate variant.

    Without ``ref``, column ``j`` is ``(y(models[j]) - y_current) / sizes[j]``: the effect's
    parameter ``indices[j]`` switched on at ``sizes[j]``. With ``ref`` (a start found by the
    inverse dynamics), the columns are the secant ``y(ref) - y_current`` and the derivatives
    ``(y(models[j]) - y(ref)) / sizes[j]`` around it.
    """

    effect: str
    models: list[GreyBox]
    sizes: list[float]
    indices: list[int]
    start: GreyBox
    ref: GreyBox | None = None


def _idim_probe(model: GreyBox, name: str, prep: Prepared, b: Bounds,
                idim: InverseDynamics) -> _Probe | None:
    """A start for force effect ``name`` from the inverse dynamics of the virtual effort.

    Without a measured effort, the identified controller applied to the measured position
    gives the effort the drive must have applied (noisy, but decimation filters it). Its
    inverse dynamics find periods, Stribeck velocities and sizes far more directly than the
    position residual, where the loop filters and delays every force.
    """
    m0 = _init_effect(model, name, prep, b)
    try:
        q = idim.fit(m0.effects, m0.plant, new=name)
    except (ValueError, np.linalg.LinAlgError):
        return None
    effect = get_effect(name)
    idx = effect.free(m0.effects)
    # only the entries the regression fitted: a row without a drive limit holds an infinite
    # one (I_IMAX), and checking the whole row denied this start to every such run
    if not np.all(np.isfinite(q[[CL.I_M, *idx]])) or q[CL.I_M] <= 0.0:
        return None
    p = m0.plant.copy()
    for i in idx:
        # the virtual effort's mass is not exactly the model's unit mass: rescale forces
        p[i] = q[i] / q[CL.I_M] if i in effect.force_parameters else q[i]
    p = _physical(p, name, b, idx)
    ref = m0.copy(plant=p)
    mods, sizes, inds = [], [], []
    for i in idx:
        if i in effect.shape_parameters:
            continue
        h = effect.probe_step(i, float(p[i]), b)
        qq = p.copy()
        qq[i] += h
        mods.append(m0.copy(plant=qq))
        sizes.append(h)
        inds.append(i)
    return _Probe(name, mods, sizes, inds, ref, ref)


def _probes(model: GreyBox, name: str, prep: Prepared, b: Bounds, y: np.ndarray
            ) -> list[_Probe]:
    """Variants of a candidate with the parameters to probe (column per parameter)."""
    m0 = _init_effect(model, name, prep, b)
    p = m0.plant
    out: list[_Probe] = []
    for changes, fixed in get_effect(name).probes(p, m0.effects, prep, b, y):
        base = p.copy()
        for i, v in fixed.items():
            base[i] = v
        mods, sizes, idx = [], [], []
        for i, v in changes.items():
            q = base.copy()
            q[i] = v
            mods.append(m0.copy(plant=q))
            sizes.append(v)
            idx.append(i)
        out.append(_Probe(name, mods, sizes, idx, m0.copy(plant=base)))
    return out


def _linear_cv(r0: np.ndarray, rows: np.ndarray, folds: np.ndarray) -> float:
    """Held-out SSE of a linearised refit ``r0 ~ J d`` (fit on one fold, score the other).

    ``rows`` is the Jacobian with one row per parameter, shape (p, n).
    """
    total = 0.0
    for k in (0, 1):
        tr, te = folds != k, folds == k
        coef = solve_ls(rows[:, tr].T, r0[tr], rcond=1e-8) if rows.shape[0] else None
        pred = matvec(rows[:, te].T, coef) if coef is not None else 0.0
        total += sumsq(r0[te] - pred)
    return total


def _eval_params(model: GreyBox, b: Bounds) -> list:
    """Free parameters while judging a candidate: plant, effects and a boxed loop.

    The loop gains may only move within a factor ``settings.loop_box`` of their current values: this
    keeps one effect from imitating another through a changed loop (with its integral action
    fitted away, Coulomb friction leaves a direction-dependent offset that looks like
    backlash; a slow position loop imitates a thermal drift).
    """
    return position_params(model, b, controller=True, controller_box=defaults().loop_box)


def _output_start(model: GreyBox, name: str, prep: Prepared, b: Bounds, y: np.ndarray,
                  mask: np.ndarray) -> GreyBox:
    m = _init_effect(model, name, prep, b)
    return get_effect(name).output_start(m, prep, b, None, y, mask, _free_positions)


_Variant = tuple[float, _Probe, np.ndarray]

# Starts tried per candidate in the real fits (Effect.n_starts): a Stribeck velocity and a
# spatial period make the error surface multimodal. The periods of the screened variants (peaks
# of the residual's spectrum against position, the inverse dynamics of the virtual effort) are
# distinct starts: the linearised screen ranks them poorly (a ripple's response through a loop
# with stiction is far from linear), and the fit only refines a period within a few per cent.
# Effects with Effect.always_fitted are fitted for real at every step, whatever their screen.


def _fitted_anyway(name: str, ratio: float) -> bool:
    """Whether ``name`` is fitted for real whatever its rank (its screen gave ``ratio``)."""
    effect = get_effect(name)
    # a screen that predicts no cut at all (a ratio above 1) has failed for an effect whose
    # screen cannot be trusted off its linear range: fitted for real
    return effect.always_fitted or (effect.fitted_when_screen_fails and ratio > 1.0)


def _fit_starts(variants: list[_Variant], name: str, b: Bounds) -> list[GreyBox]:
    """Starts of the real fits of a force effect: its best screened variants.

    For a periodic effect, variants whose periods lie within 2 % of a better one's are
    skipped (the fit refines the period that far): the starts are distinct periods.
    """
    out: list[GreyBox] = []
    periods: list[float] = []
    for v in variants:
        st = _variant_start(v, name, b)
        effect = get_effect(name)
        if effect.period_parameter is not None:
            per = float(st.plant[effect.period_parameter])
            if any(abs(per / q - 1.0) <= 0.02 for q in periods):
                continue
            periods.append(per)
        out.append(st)
        if len(out) >= effect.n_starts:
            break
    return out


def _variant_start(variant: _Variant, name: str, b: Bounds) -> GreyBox:
    """Start of a real fit from a screened variant (its linearised amplitudes, clipped)."""
    _, pr, amp = variant
    if pr.ref is not None:
        return pr.start
    q = pr.start.plant.copy()
    for i, s_, a in zip(pr.indices, pr.sizes, amp, strict=True):
        q[i] = a if np.isfinite(a) else s_
    return pr.start.copy(plant=_physical(q, name, b, pr.indices))


def _screen(m: GreyBox, y: np.ndarray, prep: Prepared, b: Bounds, settings: DiagnoseSettings,
            tag: int) -> dict[str, list[_Variant]]:
    """Linearised held-out ratio of every available candidate around model ``m``.

    Columns: the Jacobian of ``m``'s own parameters (a linearised refit) and, per candidate
    variant, finite-difference columns of its parameters; fitted on one fold, scored on the
    other. Returns the variants of each candidate, best first, with amplitude estimates.
    """
    scale = max(prep.noise.rms, 1e-9)
    r0 = (prep.x - y) / scale
    res0 = PositionFit(prep, _eval_params(m, b)).run(m, max_iter=0)
    jac = res0.jac_rows if res0.jac_rows is not None else np.zeros((0, prep.n))
    # with a load encoder the fit's residual stacks the load's error after the motor's: the
    # screen's columns are the motor position's, so is its refit
    jac = jac[:, :prep.n]
    base_lin = _linear_cv(r0, jac, prep.folds)
    probes: list[_Probe] = []
    key = hash(m.controller) if isinstance(m.controller, CascadeController) else 0
    idim_v = InverseDynamics(prep, cascade_effort(m.controller, prep), f"virtual-{tag}-{key}")
    for name in _available(m, prep, settings):
        # not for a periodic force: the regression always finds a best period in the noisy
        # virtual effort, and a cogging started there stood in for model mismatch (second
        # simulator: false on stribeck/10, 13, 16 and posdep/19; 150/168 right with it, 155
        # without it, 154 with no inverse-dynamics start on runs without a drive limit)
        if get_effect(name).kind == "force" and not get_effect(name).periodic:
            pr_idim = _idim_probe(m, name, prep, b, idim_v)
            if pr_idim is not None:
                probes.append(pr_idim)
        probes += _probes(m, name, prep, b, y)
    rows = []
    for pr in probes:
        rows += ([pr.ref] if pr.ref is not None else []) + pr.models
    ys = simulate_models(rows, prep)[0] if rows else np.zeros((0, prep.n))
    screen: dict[str, list[_Variant]] = {}
    j = 0
    for pr in probes:
        cols = []
        y_ref = y
        if pr.ref is not None:
            y_ref = ys[j]
            cols.append(-(y_ref - y) / scale)
            j += 1
        for s_ in pr.sizes:
            cols.append(-(ys[j] - y_ref) / scale / s_)
            j += 1
        Jc = np.array(cols)
        if not np.all(np.isfinite(Jc)):
            continue
        full = np.vstack([jac, Jc])
        ratio = _linear_cv(r0, full, prep.folds) / max(base_lin, 1e-300)
        # amplitude estimate on all samples, for the start of the real fit
        amp = solve_ls(full.T, r0, rcond=1e-8)[jac.shape[0]:]
        screen.setdefault(pr.effect, []).append((ratio, pr, amp))
    for variants in screen.values():
        variants.sort(key=lambda v: v[0])
    return screen


def _joint_with_prerequisite(m: GreyBox, y: np.ndarray, scores: list[CandidateScore],
                              confirmed: dict[str, dict[int, PositionFitResult]],
                              prep: Prepared, b: Bounds, settings: DiagnoseSettings,
                              floor: float, base_heldout: float,
                              fold_fit: Callable[[GreyBox, np.ndarray], PositionFitResult],
                              log: Callable[[str], None], warnings: list[str]
                              ) -> tuple[str, CandidateScore, PositionFitResult] | None:
    """An effect fitted together with the prerequisite that alone failed its held-out test.

    Friction whose level changes along the stroke, seen over one pass, is no constant level:
    Coulomb friction fitted on one half of the run predicts the other half's level wrong and
    fails, and the effect that would explain the change requires it. Each effect whose
    prerequisite was fitted for real at this step and not accepted is fitted with it, from the
    prerequisite's fold fits and the effect's probes, and judged as one candidate with the
    parameters of both. Returns ``(prerequisite, score, refit on all samples)`` or None.
    """
    by_name = {sc.effect: sc for sc in scores if sc.judged_on == "position"}
    for req, req_sc in by_name.items():
        if req not in confirmed:
            continue
        for name in effects_tried(settings):
            effect = get_effect(name)
            effects = m.effects + (req, name)
            if (req not in effect.requires or name in m.effects
                    or any(r not in effects for r in effect.requires)
                    or excluded(name, m.effects + (req,))
                    or not _shown_by(effect, prep)
                    or not effect.available(prep)):
                continue
            heldout = 0.0
            fits: dict[int, PositionFitResult] = {}
            for k in (0, 1):
                train = prep.folds != k
                base = _init_effect(confirmed[req][k].model, name, prep, b)
                starts = []
                for sizes, fixed in effect.probes(base.plant, base.effects, prep, b, y):
                    q = base.plant.copy()
                    for i, v in {**sizes, **fixed}.items():
                        q[i] = v
                    starts.append(base.copy(plant=q))
                if not starts:
                    break
                fits[k] = min((fold_fit(st, train) for st in starts), key=lambda r: r.cost)
                heldout += _position_sse(fits[k].y, prep, ~train)
            if len(fits) < 2:
                continue
            n_par = _n_params(req, m.effects + (req,)) + _n_params(name, effects)
            rho = heldout / max(base_heldout, 1e-300)
            size = min(_effect_position_size(fits[k].model, name, prep, None, fits[k].y)
                       for k in (0, 1))
            sc = CandidateScore(name, n_par, rho, "position", size / floor,
                                size >= min_position_size(settings, name) * floor,
                                f"fitted with {req}, which alone made the held-out error "
                                f"x{req_sc.heldout_ratio:.3f}")
            scores.append(sc)
            log(f"    fit    {name:28s} with {req}: held-out position error x{rho:.3f} "
                f"({n_par} par), size {size / floor:.2f} x floor")
            if not (math.isfinite(rho) and sc.size_ok
                    and sc.gain >= required_gain(settings, n_par, name, "position")):
                continue
            k_best = min(fits, key=lambda k: fits[k].cost)
            full = _refit(fits[k_best].model, prep, b, 12)
            size = _effect_position_size(full.model, name, prep, None, full.y)
            why = artefact(full.model, name, prep, b) or artefact(full.model, req, prep, b)
            kept = full.cost / max(_half_sse(y, prep), 1e-300)
            need = math.exp(-required_gain(settings, n_par, name, "position"))
            if _kept_in_refit(sc, why, size, min_position_size(settings, name), kept, need, floor,
                              warnings):
                return req, sc, full
            log(f"    {name} with {req} rejected: {sc.note}")
    return None


def _forces(m: GreyBox) -> tuple[str, ...]:
    return tuple(e for e in m.effects if get_effect(e).kind == "force")


def _effort_check_ratio(idim: InverseDynamics, base_sse: float,
                        fits: dict[int, PositionFitResult], name: str) -> float:
    """Held-out effort error of the force effects of the fold fits ``fits`` of candidate
    ``name`` against ``base_sse``, the held-out effort error of the model without the candidate
    (:meth:`InverseDynamics.cv_sse`), by inverse dynamics on the logged effort (a run diagnosed
    on its position whose law was set aside). Only the shapes (periods, Stribeck velocities)
    come from the position's fits, refined; the mass, damping and force levels are fitted to
    each training fold's effort, in the effort's unit, and judged on the sliding rows of the
    other fold, as :meth:`InverseDynamics.cv_sse` does with one start for both folds.

    A candidate whose parameters include relative variations of the friction level
    (``Effect.relative_parameters``: a level varying along the stroke) is checked with those
    held from the position's fit (:meth:`InverseDynamics.fit_levels`), as its shape is: they
    are what the position found, and solved for again on a short log's few sliding rows the
    variation's wave took the noise. On the second simulator's posdep/8 (a 1 kHz cascade
    logged at 100 Hz, 40 sliding rows per fold), a friction rising 35 % across the stroke cut
    the held-out position error 24x (x0.042) and was vetoed at x1.636 by a gradient and a wave
    of 0.12 rad fitted to the effort.
    """
    prep = idim.prep
    held = bool(get_effect(name).relative_parameters)
    sse = 0.0
    for k, res in fits.items():
        train = prep.folds_dec != k
        forces = _forces(res.model)
        q = (idim.fit_levels(forces, res.model.plant, train) if held
             else idim.fit(forces, res.model.plant, train))
        sse += sumsq((idim.u_dec - idim.predict(q))[~train & prep.sliding_dec])
    return sse / max(base_sse, 1e-300)


def _effort_check_tolerance(prep: Prepared, n_params: int) -> float:
    """How much worse a candidate may make the held-out effort error of the position mode's
    effort check: ``settings.tolerance`` plus what ``n_params`` parameters fitted to one fold
    add to the other fold's error even when the force is right, ``n_params / n``, ``n`` the
    sliding rows of the smaller training fold (the expected out-of-sample inflation of a least-
    squares fit). A short log gives the check few rows: a 1 kHz drive logged at 100 Hz for
    13 s slides on 83 decimated rows, and the Stribeck friction actually there, which cut the
    held-out position error 26x, made the effort's error x1.028 worse."""
    n = min(int(np.count_nonzero((prep.folds_dec != k) & prep.sliding_dec)) for k in (0, 1))
    return defaults().tolerance + n_params / max(n, 1)


def _search_without_effort(model: GreyBox, y: np.ndarray, prep: Prepared, b: Bounds,
                           settings: DiagnoseSettings, log: Callable[[str], None],
                           jac: np.ndarray | None, warnings: list[str], alt_loops: tuple = (),
                           budget_iter: int = 5, alt_starts: tuple = (),
                           effort_check: InverseDynamics | None = None,
                           ) -> tuple[list[Step], str, float]:
    steps = [Step(None, model, y, _rms(prep.x - y), float(np.max(np.abs(prep.x - y))), None)]
    floor_linear = max(prediction_floor(model, prep), prep.noise.rms)
    floor = floor_linear
    reason = f"reached the maximum of {settings.max_steps} effects"
    # the runners-up of the previous step and their fold fits (each restarts from its own)
    runners_up: dict[str, dict[int, PositionFitResult]] = {}
    for _ in range(settings.max_steps):
        cur = steps[-1]
        m = cur.model
        # a poorly damped model exaggerates the noise it is fed: take the lower estimate;
        # a fitted model is also smoother than the axis (less stiction, so less sensitive to
        # noise): with stiction in the loop, runs deviate by 3..6 times the sensor noise from
        # their noise-free twins (measured on simulated axes), hence the lower bound
        floor = _step_floor(m, steps, prep, None, floor_linear,
                            settings.floor_noise_factor * prep.noise.rms)
        # a residual at that floor does not end the search: the floor is a bound (three
        # sensor noises), and a friction whose cut the held-out error shows is there however
        # small; the candidates' cuts and sizes decide, as on every other step
        # ---- linearised screen (under each loop estimate, before the first effect)
        variants: dict[str, list[_Variant]] = {}
        bases = [(m, cur.y)]
        if len(steps) == 1:
            for loop in alt_loops:
                m_alt = m.copy(controller=loop)
                bases.append((m_alt, simulate_position(m_alt, prep)[0]))
        for m_s, y_s in bases:
            for name, found in _screen(m_s, y_s, prep, b, settings, len(steps)).items():
                variants[name] = sorted(variants.get(name, []) + found, key=lambda v: v[0])
        screen = {name: v[0] for name, v in variants.items()}
        ranked = sorted(screen.items(), key=lambda kv: math.log(max(kv[1][0], 1e-300))
                        / _n_params(kv[0], m.effects + (kv[0],)))
        for name, (ratio, _, _) in ranked:
            log(f"    screen {name:28s} linearised held-out error x{ratio:.3f}")
        # ---- confirm the best few with real fits on each fold (loop frozen)
        # the loop is least certain before the first effect: there, every fold fit starts
        # from each of the given loops too and keeps the better fit of its training fold
        loops = [m.controller] + (list(alt_loops) if len(steps) == 1 else [])

        def fold_fits(starts: Sequence[GreyBox], train: np.ndarray,
                      loops: list = loops) -> PositionFitResult:
            # every start under every loop (racing, only the best heat finishing, when
            # settings.race_share is below 1); an output effect's start may bring its own
            # loop (compliance: a rigid loop fitted to a compliant axis is far off): it is
            # tried first, boxed like the others
            pairs = []
            for start in starts:
                for loop in dict.fromkeys([start.controller, *loops]):
                    s0 = start.copy(controller=loop)
                    pairs.append((PositionFit(prep, _eval_params(s0, b), train), s0))
            done = [r for r in race_fits(pairs, budget_iter) if r is not None]
            return min(done, key=lambda r: r.cost)

        def fold_fit(start: GreyBox, train: np.ndarray) -> PositionFitResult:
            return fold_fits([start], train)

        base_heldout = 0.0
        base_blocks = np.zeros(0)
        # the two folds' fits are independent: on two threads at once (the same numbers)
        base_fits = run_concurrently([partial(fold_fit, m, prep.folds != k) for k in (0, 1)])
        for k in (0, 1):
            fk = base_fits[k]
            base_heldout += _position_sse(fk.y, prep, prep.folds == k)
            base_blocks = np.concatenate([base_blocks, _block_sse(fk.y, prep, k)])
        scores: list[CandidateScore] = []
        confirmed: dict[str, dict[int, PositionFitResult]] = {}
        effort_base: float | None = None
        n_confirm = settings.n_confirm + (1 if len(loops) > 1 else 0)
        chosen = ranked[:n_confirm]
        # friction is the first suspect in any servo axis, and its linearised screen is the
        # least reliable (stiction is far from linear): fit it for real while it is missing;
        # so is a candidate that was significant at the previous step but lost to the winner
        # (friction and backlash often come close: both leave a direction-dependent error)
        # and a periodic force, whose screen is no better (its linearised response to a
        # ripple misses how the ripple moves the stops of a stick-slip motion)
        chosen += [kv for kv in ranked[n_confirm:]
                   if _fitted_anyway(kv[0], kv[1][0])
                   or kv[0] in runners_up]
        for name, (ratio, _, _) in chosen:
            # after the first step, a candidate ranked among the confirmed ones is fitted for
            # real only when its screen predicts at least the smallest cut any effect needs
            # (a friction's: required_gain without the effect); it was any cut at all. A
            # compliance screened at x0.996 was fitted for 4.5 s of a 25 s run and rejected
            if (ratio >= math.exp(-required_gain(settings, _n_params(name, m.effects + (name,))))
                    and len(steps) > 1
                    and name not in runners_up
                    and not _fitted_anyway(name, ratio)):
                scores.append(CandidateScore(
                    name, _n_params(name, m.effects + (name,)), ratio, "position (linearised)",
                    note="not fitted: its screen predicts less than the smallest cut an effect "
                         "needs"))
                continue
            heldout = 0.0
            cand_blocks = np.zeros(0)
            fits: dict[int, PositionFitResult] = {}

            def candidate_fit(k: int, name: str = name, m: GreyBox = m, y: np.ndarray = cur.y,
                              variants: dict = variants, runners_up: dict = runners_up,
                              first: bool = len(steps) == 1) -> PositionFitResult:
                train = prep.folds != k
                if get_effect(name).kind == "output":
                    starts = [_output_start(m, name, prep, b, y, train)]
                else:
                    starts = _fit_starts(variants[name], name, b)
                    if first:
                        # a model of the loop fitted with this very effect (the drive limit's
                        # fit holds a Coulomb force) is a start too
                        starts += [st.copy() for st in alt_starts if st.effects == (name,)]
                    starts += _equation_error_starts(m, name, prep, b, train)
                if name in runners_up:
                    starts.append(_carried_over(m, name, runners_up[name][k]))
                return fold_fits(starts, train)

            # each fold's starts and fits are its own: both folds on two threads at once
            fold_results = run_concurrently([partial(candidate_fit, k) for k in (0, 1)])
            for k in (0, 1):
                train = prep.folds != k
                res = fold_results[k]
                fits[k] = res
                heldout += _position_sse(res.y, prep, ~train)
                cand_blocks = np.concatenate([cand_blocks, _block_sse(res.y, prep, k)])
            n_par = _n_params(name, fits[0].model.effects)
            rho, left_out, block_note = _judged_ratio(heldout, base_heldout, cand_blocks,
                                                      base_blocks)
            note = f"linearised x{ratio:.3f}"
            if left_out is not None:
                a, z = _blocks(prep)[left_out]
                t = prep.inputs.t
                note += f"; {block_note} (t = {t[a]:.3g}..{t[z - 1]:.3g} s)"
            sizes = [_effect_position_size(fits[k].model, name, prep, None, fits[k].y)
                     for k in (0, 1)]
            size = min(sizes)
            sc = CandidateScore(name, n_par, rho, "position", size / floor,
                                size >= min_position_size(settings, name) * floor, note)
            _check_consistency(sc, cand_blocks, base_blocks, left_out, settings)
            effort_note = ", not consistent over the blocks" if not sc.size_ok and (
                "not consistent" in sc.note) else ""
            if effort_check is not None and get_effect(name).kind == "force":
                if effort_base is None:  # the model without the candidate: once per step
                    effort_base, _ = effort_check.cv_sse(_forces(m), m.plant)
                effort_ratio = _effort_check_ratio(effort_check, effort_base, fits, name)
                effort_note += f", effort x{effort_ratio:.3f}"
                if effort_ratio > 1.0 + _effort_check_tolerance(prep, n_par):
                    # the logged effort is a measured force even where the law computed from it
                    # is not the drive's: a force it contradicts is no force of the axis (a
                    # ripple of 0.8 % of the Coulomb level fitted beside a backlash, x2.44). Its
                    # verdict is coarse on a short slow log (30-40 sliding rows per fold): a
                    # friction level varying along the stroke that was there went too (x1.76,
                    # as the effort's own search judged it), a miss rather than a false effect
                    sc.size_ok = False
                    sc.note += (f"; rejected: it makes the held-out effort error worse "
                                f"(x{effort_ratio:.3f})")
                    effort_note += " rejected"
            scores.append(sc)
            confirmed[name] = fits
            log(f"    fit    {name:28s} held-out position error x{rho:.3f} ({n_par} par), "
                f"size {size / floor:.2f} x floor{effort_note}"
                + (f" (one block left out: x{heldout / max(base_heldout, 1e-300):.3f} with it)"
                   if left_out is not None else ""))
        for name, (ratio, _, _) in [kv for kv in ranked if kv not in chosen]:
            n_par = _n_params(name, m.effects + (name,))
            scores.append(CandidateScore(name, n_par, ratio, "position (linearised)",
                                         note="not fitted: ranked below the confirmed ones"))
        accepted = None
        pool = [s for s in scores if s.judged_on == "position"]
        while True:
            winner = _pick(pool, settings)
            if winner is None:
                break
            fits = confirmed[winner.effect]
            # refit on all samples, the loop free again, from the better fold fit
            k_best = min(fits, key=lambda k: fits[k].cost)
            full = _refit(fits[k_best].model, prep, b, 12)
            size = _effect_position_size(full.model, winner.effect, prep, None, full.y)
            why = artefact(full.model, winner.effect, prep, b)
            # the refit on all samples must keep at least the cut the held-out test required
            # (an in-sample fit does better than a held-out one): a gain that vanished there
            # was a fold's accident
            kept = full.cost / max(_half_sse(cur.y, prep), 1e-300)
            need = math.exp(-required_gain(settings, winner.n_params, winner.effect,
                                               winner.judged_on))
            if _kept_in_refit(winner, why, size, min_position_size(settings, winner.effect), kept,
                              need, floor, warnings):
                accepted = (winner, full)
                break
            log(f"    {winner.effect} rejected: {winner.note}")
            pool = [s for s in pool if s is not winner]
        if accepted is None:
            joint = _joint_with_prerequisite(m, cur.y, scores, confirmed, prep, b, settings,
                                             floor, base_heldout, fold_fit, log, warnings)
            if joint is not None:
                m_req = joint[2].model.without(joint[1].effect)
                y_req, _ = simulate_position(m_req, prep)
                if not np.all(np.isfinite(y_req)):
                    # the prerequisite's step must be reported with finite numbers
                    joint = None
            if joint is None:
                reason = "no candidate improves the held-out position error significantly"
                cur.rejected = scores
                break
            req, sc_j, full = joint
            # two steps: the prerequisite (the joint model without the effect, not judged
            # alone) and the effect (the joint model, judged with both)
            steps.append(Step(req, m_req, y_req, _rms(prep.x - y_req),
                              float(np.max(np.abs(prep.x - y_req))), None, scores, None))
            steps.append(Step(sc_j.effect, full.model, full.y, _rms(prep.x - full.y),
                              float(np.max(np.abs(prep.x - full.y))), None, scores,
                              sc_j.heldout_ratio))
            runners_up = {}
            log(f"  + {req} with {sc_j.effect}: position rms "
                f"{_length(prep, steps[-1].position_rms)}")
            continue
        winner, full = accepted
        runners_up = {sc.effect: confirmed[sc.effect] for sc in scores
                      if sc is not winner and sc.size_ok and sc.judged_on == "position"
                      and sc.gain >= required_gain(settings, sc.n_params, sc.effect, sc.judged_on)}
        step = Step(winner.effect, full.model, full.y, _rms(prep.x - full.y),
                    float(np.max(np.abs(prep.x - full.y))), None, scores, winner.heldout_ratio)
        steps.append(step)
        log(f"  + {winner.effect}: position rms {_length(prep, step.position_rms)}")
    return steps, reason, floor


def _equation_error_starts(m: GreyBox, name: str, prep: Prepared, b: Bounds,
                           train: np.ndarray) -> list[GreyBox]:
    """Starts of a Stribeck friction's fold fit with the loop and friction found together by
    equation error on the training fold (:mod:`fricbench.sysid.diagnose.equation_error`).

    The loop of the model so far was fitted with Coulomb friction alone, and with a strong
    Stribeck friction that loop is far off (on the second simulator's stribeck/10 its
    velocity gain sat on its lower bound and its acceleration feedforward on its upper one),
    so a Stribeck term added to it finds nothing (x1.05). From the equation error's loop and
    friction the fit reaches the true loop's error (84 -> 0.85 um)."""
    if (name != "stribeck_friction" or "coulomb_friction" not in m.effects
            or not isinstance(m.controller, CascadeController)):
        return []
    out = []
    # under the model's own command delay (a loop property, found with the first friction):
    # another delay would come in unjudged with the candidate
    delay = int(m.plant[CL.I_DELAY]) if prep.inputs.n_loop == 1 else 0
    for fit in loop_by_equation_error(prep, b, ("coulomb_friction", name), n_best=1,
                                      mask=train, delays=(delay,)):
        st = m.copy(controller=fit.model.controller, effects=m.effects + (name,))
        st.plant[CL.I_B] = min(float(fit.model.plant[CL.I_B]), b.damping_max)
        st.plant[CL.I_VS] = float(fit.model.plant[CL.I_VS])
        for i in (CL.I_FC, CL.I_FS):
            effect = get_effect("coulomb_friction" if i == CL.I_FC else name)
            st.plant[i] = effect.clip(i, float(fit.model.plant[i]), b)
        out.append(st)
    return out


def _carried_over(m: GreyBox, name: str, prev: PositionFitResult) -> GreyBox:
    """Model ``m`` with effect ``name`` at the values a fold fit of the previous step gave it.

    A runner-up (significant, beaten by the winner) was fitted one step ago; its parameters
    there are a start near its own basin. From the linearised screen alone, a fit of a few
    iterations may land in another (a periodic friction variation: held-out x0.68 from its
    previous fit, x0.82 from the screen, on one run, the choice flipping with the BLAS kernel's
    rounding).
    """
    effect = get_effect(name)
    effects = m.effects + (name,)
    p = m.plant.copy()
    for i in effect.free(effects):
        p[i] = prev.model.plant[i]
    return m.copy(plant=p, effects=effects)


def _heldout_position_sse(model: GreyBox, prep: Prepared, b: Bounds, budget_iter: int
                          ) -> float:
    """Held-out position error of ``model``: fitted on each fold, scored on the other."""
    total = 0.0
    fits = run_concurrently([partial(PositionFit(prep, _eval_params(model, b),
                                                 prep.folds != k).run, model,
                                     max_iter=budget_iter) for k in (0, 1)])
    for k in (0, 1):
        total += _position_sse(fits[k].y, prep, prep.folds == k)
    return total


def _redundant_effect(model: GreyBox, prep: Prepared, b: Bounds, settings: DiagnoseSettings,
                      log: Callable[[str], None], budget_iter: int = 5
                      ) -> tuple[str, float] | None:
    """An effect of ``model`` that the others have made unnecessary, or None.

    Forward selection adds an effect when it helps the model of that step; a later effect
    may explain the same residual better (position-dependent friction stands in for the
    Stribeck hump until the hump is in). Each effect no other one requires is taken out
    and the model refitted on each fold: when the held-out error rises by less than the gain
    the effect would need to be added (:func:`required_gain`), it is redundant.
    Returns the least useful such effect and its ``-ln`` held-out gain.
    """
    effects = model.effects
    if len(effects) < 2:
        return None
    with_sse = _heldout_position_sse(model, prep, b, budget_iter)
    worst: tuple[str, float] | None = None
    for name in effects:
        if any(name in get_effect(o).requires for o in effects if o != name):
            continue
        without_sse = _heldout_position_sse(model.without(name), prep, b, budget_iter)
        gain = -math.log(max(with_sse, 1e-300) / max(without_sse, 1e-300))
        need = required_gain(settings, _n_params(name, effects), name, "position")
        log(f"    without {name:28s} held-out position error x{math.exp(gain):.3f} "
            f"(needs x{math.exp(need):.3f})")
        if gain < need and (worst is None or gain - need < worst[1]):
            worst = (name, gain - need)
    return None if worst is None else (worst[0], worst[1])


def _refit(start: GreyBox, prep: Prepared, b: Bounds, max_iter: int) -> PositionFitResult:
    """Refit every parameter of an accepted model from several starting loops.

    The loop estimated before the effect was known is biased by it (a linear loop fitted to
    a thermal drift has hardly any position gain), so besides the current loop the best of
    the standard starting loops is refined too, and the lower error wins.
    """
    from fricbench.sysid.diagnose.baselines import starting_controllers

    grid = [start.copy(controller=c) for c in starting_controllers(prep.inputs.loop_ts)]
    ys = simulate_models(grid, prep)[0]
    sse = np.array([_position_sse(y, prep, np.ones(prep.n, dtype=bool)) for y in ys])
    candidates = [start] + [grid[i] for i in np.argsort(sse)[:1] if np.isfinite(sse[i])]
    best: PositionFitResult | None = None
    # whatever the start, the integral action may not collapse (see _eval_params)
    c0 = start.controller
    ki_min = (c0.ki / c0.wv) / defaults().loop_box if isinstance(c0, CascadeController) else 0.0
    params = [position_params(m, b, controller=True,
                              controller_box=defaults().loop_box if k == 0 else None,
                              ki_min_ratio=ki_min) for k, m in enumerate(candidates)]
    # independent fits: on two threads at once (the same numbers)
    for res in run_concurrently([partial(PositionFit(prep, p).run, m, max_iter=max_iter)
                                 for p, m in zip(params, candidates, strict=True)]):
        if best is None or res.cost < best.cost:
            best = res
    assert best is not None
    return best


def _half_sse(y: np.ndarray, prep: Prepared) -> float:
    scale = max(prep.noise.rms, 1e-9)
    return 0.5 * sumsq((prep.x - y) / scale)


def _physical(q: np.ndarray, name: str, b: Bounds, indices: Sequence[int]) -> np.ndarray:
    """Clip a linearised start of effect ``name`` (entries ``indices``) into physical ranges."""
    effect = get_effect(name)
    out = q.copy()
    for i in indices:
        out[i] = effect.clip(i, float(out[i]), b)
    return out


def forward_selection(model: GreyBox, y: np.ndarray, prep: Prepared, b: Bounds, *,
                      idim: InverseDynamics | None = None, w: np.ndarray | None = None,
                      jac: np.ndarray | None = None, settings: DiagnoseSettings | None = None,
                      alt_loops: tuple = (), alt_starts: tuple = (),
                      effort_check: InverseDynamics | None = None,
                      log: Callable[[str], None] | None = None) -> SearchResult:
    """Add effects to the linear ``model`` while they help on held-out data.

    Parameters
    ----------
    model : GreyBox
        The fitted linear model.
    y : ndarray
        Its free-run position, m.
    prep : Prepared
    b : Bounds
    idim : InverseDynamics, optional
        The effort regression (runs with an effort).
    w : ndarray, optional
        Injected effort of the run.
    jac : ndarray, optional
        Jacobian of the linear output-error fit, one row per parameter (runs without effort).
    settings : DiagnoseSettings, optional
        Default: :func:`~fricbench.sysid.diagnose.settings.defaults`.
    alt_loops : tuple of CascadeController
        Other loop estimates the first step's fits also start from (runs without effort).
    alt_starts : tuple of GreyBox
        Models of one effect each (a loop fitted with it) the first step's fit of that effect
        also starts from (runs without effort).
    effort_check : InverseDynamics, optional
        The effort regression of a run diagnosed on its position although it logs an effort
        (its law was set aside): a force effect that makes the held-out effort error worse by
        more than ``settings.tolerance`` and what its parameters' fit on few rows adds
        (:func:`_effort_check_tolerance`) is rejected (without ``idim`` only).
    log : callable, optional
        Receives progress lines.

    Returns
    -------
    SearchResult
    """
    settings = settings or defaults()
    log = log or (lambda _s: None)
    t0 = time.perf_counter()
    warnings: list[str] = []
    if idim is not None:
        steps, reason, floor = _search_with_effort(model, prep, idim, b, settings, w, log,
                                                   warnings)
        # no effect may make the free-run position worse: prune the final model, and search
        # again without what was pruned (so that every step is one the final model keeps)
        for _ in range(len(effects_tried(settings))):
            pruned = _position_prune(steps[-1].model, prep, idim, w, log)
            if not pruned:
                break
            for name, with_, without in pruned:
                ratio = next((st.heldout_ratio for st in steps if st.effect == name), None)
                cut = f" ({100 * (1 - ratio):.1f} % held-out effort error cut)" if ratio else ""
                warnings.append(f"rejected {name}: it is significant on the effort{cut} but "
                                f"makes the free-run position worse ({_length(prep, without)} "
                                f"-> {_length(prep, with_)} rms)")
            dropped = {name for name, _, _ in pruned}
            settings = dataclasses.replace(settings, candidates=tuple(
                c for c in effects_tried(settings) if c not in dropped))
            steps, reason, floor = _search_with_effort(model, prep, idim, b, settings, w, log,
                                                       warnings)
    else:
        steps, reason, floor = _search_without_effort(model, y, prep, b, settings, log, jac,
                                                      warnings, alt_loops,
                                                      alt_starts=alt_starts,
                                                      effort_check=effort_check)
        # backward elimination: an effect a later one made unnecessary is dropped and the
        # search run again without it (so that every step is one the final model keeps)
        for _ in range(len(effects_tried(settings))):
            redundant = _redundant_effect(steps[-1].model, prep, b, settings, log)
            if redundant is None:
                break
            name = redundant[0]
            kept_steps, kept_reason, kept_floor = steps, reason, floor
            kept_warnings = list(warnings)
            need = required_gain(settings, _n_params(name, steps[-1].model.effects), name,
                                 "position")
            warnings.append(f"dropped {name}: once the later effects are in, it no longer "
                            "cuts the held-out position error by what adding it requires")
            log(f"  - {name}: redundant, search again without it")
            settings = dataclasses.replace(settings, candidates=tuple(
                c for c in effects_tried(settings) if c != name))
            steps, reason, floor = _search_without_effort(model, y, prep, b, settings, log,
                                                          jac, warnings, alt_loops,
                                                          alt_starts=alt_starts,
                                                          effort_check=effort_check)
            kept = kept_steps[-1]
            claims = {e for e in kept.model.effects if e != name and not get_effect(e).friction}
            if (claims <= set(steps[-1].model.effects)
                    and steps[-1].position_rms > math.exp(need) * kept.position_rms):
                # the test refitted the model without it from the final loop; the search
                # run again from the linear loop may not reach that fit (the second
                # simulator's thermal/26: a drift judged redundant at x1.20, and the search
                # without it ended at 7.5 um against 1.3 um with it): the drop is undone.
                # Not when that would bring back an effect other than friction that the
                # search without it did not find again (control/28: a false cogging)
                log(f"  + {name} kept: without it the search ends at "
                    f"{_length(prep, steps[-1].position_rms)} rms, against "
                    f"{_length(prep, kept.position_rms)} with it")
                steps, reason, floor = kept_steps, kept_reason, kept_floor
                warnings[:] = kept_warnings
                break
    # a repeated search rejects the same artefacts again: each warning once
    return SearchResult(steps, reason, floor, time.perf_counter() - t0,
                        list(dict.fromkeys(warnings)))


def step_parameters(step: Step, force_unit: str) -> dict[str, dict[str, float]]:
    """Parameters of every effect of a step's model, in SI units."""
    return {e: describe_parameters(e, step.model.plant, force_unit) for e in step.model.effects}
