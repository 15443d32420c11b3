"""``fricbench reproduce``: the paper's experiment end to end on the simulated default axis.

Wang & Zhang (2023), Sections 3-4, with the simulator in place of the machine:

1. simulate M-serial and curve runs for training and, with another noise level and noise seed,
   for testing (the held-out runs; nothing is evaluated on data it was trained on);
2. identify the transfer function and ``v_break``, extract the nonlinear friction error;
3. fit every predictor on the training runs, predict the held-out runs; the prediction error
   is ``x_true - x_pred`` (the true table position of the held-out run: its measurement noise
   is not an error of the predictor);
4. pre-compensate (``x_r' = x_r + e_pred``) and measure the *actual* tracking error on the
   simulator;
5. the cross-trajectory case: trained without the curve (M-serial and a ``random`` training
   run), evaluated on the curve;
6. the spread over network seeds: TF+LSTM is refitted on the same training runs from each
   further seed of ``ReproduceConfig.seeds`` and steps 3-4 repeated for it; the targets are
   judged on the median over the seeds (one network is one draw: single networks from
   different seeds give held-out ratios from about 1.5x to 7x).

:func:`reproduce` returns a :class:`ReproduceResult`; :func:`write_json` writes the summary
atomically, :func:`plot_figures` draws the counterparts of the paper's Figures 11-18, and
:func:`format_report` prints our numbers beside the paper's.
"""

from __future__ import annotations

import inspect
import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fricbench._atomic import atomic_write
from fricbench._validation import check_int, check_range
from fricbench.axis import Axis, SimulationResult, simulate
from fricbench.predictors import make_predictor, predictor_registry
from fricbench.predictors.base import Predictor
from fricbench.predictors.precomp import precompensation_offset
from fricbench.sysid.friction_error import extract_friction_error, identify_v_break_multi
from fricbench.trajectories import make_trajectory
from fricbench.trajectories.base import Reference

__all__ = ["ReproduceConfig", "TrajectoryReport", "SeedResult", "ReproduceResult", "reproduce",
           "write_json", "plot_figures", "format_report", "PAPER", "TARGETS"]

#: The paper's numbers (Wang & Zhang 2023, Sec. 4), um.
PAPER: dict[str, Any] = {
    "v_break_mm_s": 1.98,
    "m_serial": {"tracking_max_um": 40.0, "tf_max_um": 20.0, "tf_lstm_max_um": 3.5},
    "curve": {"tracking_max_um": 44.0, "tf_max_um": 27.0, "tf_lstm_max_um": 8.0},
}

#: Reproduction targets (held-out runs): TF / TF+LSTM ratios and the pre-compensation cut.
TARGETS = {"m_serial_ratio": 5.0, "curve_ratio": 3.0, "m_serial_precomp_cut": 0.70,
           "beat_paper_ratio": 10.0}

TRAJECTORIES = ("m_serial", "curve")


@dataclass(frozen=True)
class ReproduceConfig:
    """Settings of :func:`reproduce` (all SI).

    Parameters
    ----------
    quantization : float
        Encoder step of every run, m (0.25 um: 10,000 pulses/rev, x4, 10 mm lead).
    train_noise_std, test_noise_std : float
        Measurement noise of the training and the held-out runs, m.
    train_seed, test_seed : int
        Noise seed of the first training / held-out run (the next runs count up).
    predictors : tuple of str
        Registered ids fitted and compared (``tf`` and ``tf+lstm`` are always included).
    predictor_params : dict
        Overrides passed to every predictor whose constructor takes them (e.g.
        ``{"max_epochs": 3}`` for a smoke run); the ``seed`` of ``tf+lstm`` comes from
        ``seeds``.
    precomp_grid : tuple of (int, float, int[, bool])
        ``(iterations, gain, advance[, inverse])`` settings of :func:`precompensation_offset`
        tried on
        the *training* references (fresh noise seeds); the best one per predictor is then
        applied to the held-out run and reported as "tuned" beside the paper's one-shot
        ``(1, 1.0, 0)``.
    cross_training : tuple of tuple
        ``(trajectory id, params)`` of the cross-trajectory training runs (no curve):
        M-serial and one cycle of ``reversal_sine``, whose reversals span the curve's
        accelerations at zero velocity (0.001..1.4 m/s^2); about 40,000 samples.
    seeds : tuple of int
        Network seeds of ``tf+lstm`` (its ``seed``; the training runs stay the same). The
        first is the run everything else reports (every predictor, the cross-trajectory case,
        the figures); for each further seed ``tf+lstm`` alone is refitted, with the full
        training, and evaluated on the held-out runs as in steps 3-4. The targets are judged
        on the median over all of them.
    verbose : bool
        Print progress.
    """

    quantization: float = 0.25e-6
    train_noise_std: float = 0.10e-6
    test_noise_std: float = 0.05e-6
    train_seed: int = 1
    test_seed: int = 101
    predictors: tuple[str, ...] = ("tf", "tf+lstm", "tf+stribeck", "tf+lstm-phys",
                                   "greybox", "greybox+lstm")
    predictor_params: dict[str, Any] = field(default_factory=dict)
    precomp_grid: tuple[tuple[Any, ...], ...] = (
        (1, 1.0, 0), (1, 0.7, 0), (1, 1.0, 3), (1, 0.85, 3), (1, 0.7, 3), (1, 0.5, 3),
        (1, 1.0, 0, True), (1, 1.0, 2, True), (1, 0.85, 2, True), (1, 1.0, 4, True),
        (1, 0.7, 5), (1, 0.5, 5), (3, 0.5, 3), (5, 0.3, 3), (5, 0.5, 3), (10, 0.5, 3))
    cross_training: tuple[tuple[str, dict[str, Any]], ...] = (
        ("m_serial", {}), ("reversal_sine", {"cycles": 1}))
    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    verbose: bool = True

    def __post_init__(self) -> None:
        check_range("quantization", self.quantization, 0.0, 1e-4, "m")
        check_range("train_noise_std", self.train_noise_std, 0.0, 1e-4, "m")
        check_range("test_noise_std", self.test_noise_std, 0.0, 1e-4, "m")
        check_int("train_seed", self.train_seed, 0)
        check_int("test_seed", self.test_seed, 0)
        if self.test_seed == self.train_seed:
            raise ValueError(f"test_seed={self.test_seed}: expected a seed other than "
                             "train_seed (held-out runs must differ from the training runs)")
        if not self.precomp_grid:
            raise ValueError("precomp_grid is empty: expected (iterations, gain, advance"
                             "[, inverse]) settings, e.g. ((1, 1.0, 0),)")
        for g in self.precomp_grid:
            if len(g) not in (3, 4):
                raise ValueError(f"precomp_grid entry {g!r}: expected (iterations, gain, "
                                 "advance) or (iterations, gain, advance, inverse)")
        if not isinstance(self.predictor_params, dict):
            raise TypeError(f"predictor_params={self.predictor_params!r}: expected a dict")
        if not isinstance(self.seeds, tuple) or not self.seeds:
            raise ValueError(f"seeds={self.seeds!r}: expected a non-empty tuple of network "
                             "seeds, e.g. (0, 1, 2, 3, 4)")
        for i, seed in enumerate(self.seeds):
            check_int(f"seeds[{i}]", seed, 0)
        if len(set(self.seeds)) != len(self.seeds):
            raise ValueError(f"seeds={self.seeds!r}: expected distinct seeds")


@dataclass(frozen=True)
class TrajectoryReport:
    """Results on one held-out trajectory.

    Attributes
    ----------
    name : str
    t, x_ref : ndarray
        Time (s) and reference (m) of the held-out run.
    tracking_error : ndarray
        Actual tracking error ``x_ref - x_true``, m.
    friction_error : ndarray
        Nonlinear friction error extracted from the held-out measurement, m.
    presliding : ndarray of bool
        Pre-sliding windows.
    prediction_errors : dict of str to ndarray
        ``x_true - x_pred`` per predictor id, m.
    max_um : dict of str to float
        Max ``|x_true - x_pred|`` per predictor id, um.
    precomp_errors : dict of str to ndarray
        Actual tracking error with each feedforward: ``"none"``, ``"<id>"`` (the paper's
        one-shot ``x_r + e_pred``) and ``"<id> tuned"`` (the setting chosen on the training
        references), m.
    precomp_max_um : dict of str to float
    precomp_settings : dict of str to tuple
        ``(iterations, gain, advance, inverse)`` behind each ``"<id> tuned"`` entry.
    """

    name: str
    t: np.ndarray = field(repr=False)
    x_ref: np.ndarray = field(repr=False)
    tracking_error: np.ndarray = field(repr=False)
    friction_error: np.ndarray = field(repr=False)
    presliding: np.ndarray = field(repr=False)
    prediction_errors: dict[str, np.ndarray] = field(repr=False)
    max_um: dict[str, float]
    precomp_errors: dict[str, np.ndarray] = field(repr=False)
    precomp_max_um: dict[str, float]
    precomp_settings: dict[str, tuple[int, float, int, bool]] = field(default_factory=dict)

    @property
    def tracking_max_um(self) -> float:
        """Max actual tracking error without compensation, um."""
        return float(np.max(np.abs(self.tracking_error)) * 1e6)

    def ratio(self, predictor_id: str) -> float:
        """TF-only max prediction error over that of ``predictor_id``."""
        return self.max_um["tf"] / self.max_um[predictor_id]


def _lstm_cuts(rep: TrajectoryReport, pid: str = "tf+lstm") -> dict[str, float]:
    """Cut of the max tracking error by ``pid``'s pre-compensation: one-shot, model-inverse,
    tuned (a tuned setting equal to a one-shot one is reported as that one)."""
    none = rep.precomp_max_um["none"]
    one = rep.precomp_max_um[pid]
    inv = rep.precomp_max_um.get(f"{pid} inverse", one)
    tuned = rep.precomp_max_um.get(f"{pid} tuned")
    if tuned is None:  # the tuned setting was (1, 1.0, 0[, inverse]): one of the others
        tuned = inv if rep.precomp_settings.get(f"{pid} tuned", (0, 0, 0, False))[3] else one
    return {"one_shot": 1 - one / none, "inverse": 1 - inv / none, "tuned": 1 - tuned / none}


@dataclass(frozen=True)
class SeedResult:
    """``tf+lstm`` trained from one network seed, on the held-out runs.

    Attributes
    ----------
    seed : int
        The predictor's ``seed``.
    max_um : dict of str to float
        Max ``|x_true - x_pred|`` per trajectory (``"m_serial"``, ``"curve"``), um.
    ratio : dict of str to float
        TF-only max prediction error over TF+LSTM's, per trajectory.
    precomp_cut : dict of str to float
        Cut of the M-serial max tracking error: ``"one_shot"``, ``"inverse"``, ``"tuned"``
        and ``"best"`` (the largest of the three, what the target is judged on), fractions.
    fit_seconds : float
        Wall-clock time of the fit, s.
    """

    seed: int
    max_um: dict[str, float]
    ratio: dict[str, float]
    precomp_cut: dict[str, float]
    fit_seconds: float

    @classmethod
    def from_reports(cls, seed: int, reports: dict[str, TrajectoryReport],
                     tf_max_um: dict[str, float], fit_seconds: float) -> SeedResult:
        """Collect the figures of ``tf+lstm`` from its held-out reports."""
        cuts = _lstm_cuts(reports["m_serial"])
        cuts["best"] = max(cuts.values())
        max_um = {n: reports[n].max_um["tf+lstm"] for n in TRAJECTORIES}
        return cls(seed, max_um, {n: tf_max_um[n] / max_um[n] for n in TRAJECTORIES}, cuts,
                   fit_seconds)


def spread(values: Sequence[float]) -> dict[str, float]:
    """Median, min and max of ``values``."""
    v = np.asarray(values, dtype=float)
    return {"median": float(np.median(v)), "min": float(v.min()), "max": float(v.max())}


@dataclass(frozen=True)
class ReproduceResult:
    """Everything :func:`reproduce` measured.

    Attributes
    ----------
    tf_num, tf_den : list of float
        The identified TF-only transfer function (descending powers of ``s``).
    tf_lstm_num, tf_lstm_den : list of float
        The transfer function inside TF+LSTM (fitted outside the pre-sliding windows).
    v_break_mm_s : float
        Break velocity identified from the training runs.
    train_seconds : float
        Wall-clock time of fitting TF+LSTM (TF, v_break and network).
    fit_seconds : dict of str to float
        Fit time of every predictor.
    trajectories : dict of str to TrajectoryReport
        ``"m_serial"`` and ``"curve"``.
    cross : TrajectoryReport
        The curve, predicted by predictors trained without it.
    best : str
        Registered id with the best worst-case TF / predictor ratio.
    config : ReproduceConfig
    n_train_samples : int
    seeds : list of SeedResult
        ``tf+lstm`` from every seed of ``config.seeds``, the first being the one above.
    seconds : float
        Wall-clock time of the whole reproduction, s.
    """

    tf_num: list[float]
    tf_den: list[float]
    tf_lstm_num: list[float]
    tf_lstm_den: list[float]
    v_break_mm_s: float
    train_seconds: float
    fit_seconds: dict[str, float]
    trajectories: dict[str, TrajectoryReport]
    cross: TrajectoryReport
    best: str
    config: ReproduceConfig
    n_train_samples: int
    seeds: list[SeedResult] = field(default_factory=list)
    seconds: float = 0.0

    def seed_spread(self) -> dict[str, dict[str, float]]:
        """Median, min and max over the seeds of each figure of :class:`SeedResult`."""
        out = {f"{n}_ratio": spread([r.ratio[n] for r in self.seeds]) for n in TRAJECTORIES}
        out.update({f"{n}_max_um": spread([r.max_um[n] for r in self.seeds])
                    for n in TRAJECTORIES})
        for key in ("one_shot", "inverse", "tuned", "best"):
            out[f"m_serial_precomp_cut_{key}"] = spread([r.precomp_cut[key] for r in self.seeds])
        return out

    def targets(self) -> dict[str, dict[str, Any]]:
        """The paper's targets judged on the median over the seeds: value, threshold, met."""
        sp = self.seed_spread()
        rows = {"m_serial_ratio": ("m_serial_ratio", TARGETS["m_serial_ratio"]),
                "curve_ratio": ("curve_ratio", TARGETS["curve_ratio"]),
                "m_serial_precomp_cut": ("m_serial_precomp_cut_best",
                                         TARGETS["m_serial_precomp_cut"])}
        return {name: {**sp[key], "target": thr, "met": sp[key]["median"] >= thr,
                       "met_by_seeds": sum(v >= thr for v in self._values(key))}
                for name, (key, thr) in rows.items()}

    def _values(self, key: str) -> list[float]:
        if key.endswith("_ratio"):
            return [r.ratio[key[:-6]] for r in self.seeds]
        return [r.precomp_cut[key.removeprefix("m_serial_precomp_cut_")] for r in self.seeds]

    def to_json(self) -> dict[str, Any]:
        """The JSON summary (ratios, pre-compensation cuts, targets; context under extra keys)."""
        out: dict[str, Any] = {
            "tf": {"num": self.tf_num, "den": self.tf_den},
            "v_break_mm_s": self.v_break_mm_s,
            "train_seconds": self.train_seconds,
        }
        for name in TRAJECTORIES:
            rep = self.trajectories[name]
            out[name] = {
                "tracking_max_um": rep.tracking_max_um,
                "tf_max_um": rep.max_um["tf"],
                "tf_lstm_max_um": rep.max_um["tf+lstm"],
                "precomp": {
                    "none_max_um": rep.precomp_max_um["none"],
                    "tf_precomp_max_um": rep.precomp_max_um["tf"],
                    "tf_lstm_precomp_max_um": rep.precomp_max_um["tf+lstm"],
                },
                "predictors_max_um": dict(rep.max_um),
                "precomp_all_max_um": dict(rep.precomp_max_um),
                "precomp_tuned_settings": {k: list(v) for k, v in rep.precomp_settings.items()},
            }
        out["cross_trajectory"] = {
            "trained_on": [tid for tid, _ in self.config.cross_training],
            "evaluated_on": "curve",
            "tracking_max_um": self.cross.tracking_max_um,
            "predictors_max_um": dict(self.cross.max_um),
            "precomp_all_max_um": dict(self.cross.precomp_max_um),
            "precomp_tuned_settings": {k: list(v)
                                       for k, v in self.cross.precomp_settings.items()},
        }
        out["best_predictor"] = {
            "id": self.best,
            "ratio_m_serial": self.trajectories["m_serial"].ratio(self.best),
            "ratio_curve": self.trajectories["curve"].ratio(self.best),
        }
        out["seeds"] = {
            "seeds": [r.seed for r in self.seeds],
            "per_seed": [{"seed": r.seed, "max_um": r.max_um, "ratio": r.ratio,
                          "m_serial_precomp_cut": r.precomp_cut, "fit_seconds": r.fit_seconds}
                         for r in self.seeds],
            "spread": self.seed_spread(),
            "targets": self.targets(),
            "seconds": self.seconds,
        }
        out["tf_lstm_tf"] = {"num": self.tf_lstm_num, "den": self.tf_lstm_den}
        out["fit_seconds"] = dict(self.fit_seconds)
        out["n_train_samples"] = self.n_train_samples
        out["paper"] = PAPER
        cfg = self.config
        out["config"] = {
            "quantization_m": cfg.quantization, "train_noise_std_m": cfg.train_noise_std,
            "test_noise_std_m": cfg.test_noise_std, "train_seed": cfg.train_seed,
            "test_seed": cfg.test_seed, "predictors": list(cfg.predictors),
            "predictor_params": dict(cfg.predictor_params),
            "precomp_grid": [list(g) for g in cfg.precomp_grid],
            "seeds": list(cfg.seeds),
            "command": "fricbench reproduce",
        }
        return out


# -- the pipeline -----------------------------------------------------------------------------
def _log(cfg: ReproduceConfig, msg: str) -> None:
    if cfg.verbose:
        print(msg, flush=True)


def _make(pid: str, overrides: dict[str, Any], verbose: bool) -> Predictor:
    factory = predictor_registry.spec(pid).load()
    accepted = set(inspect.signature(factory).parameters)
    kwargs = {k: v for k, v in overrides.items() if k in accepted}
    if "verbose" in accepted and "verbose" not in overrides:
        kwargs["verbose"] = 25 if verbose else 0
    return make_predictor(pid, **kwargs)


def _fit_all(ids: Sequence[str], runs: list[SimulationResult], cfg: ReproduceConfig,
             label: str, seed: int) -> tuple[dict[str, Predictor], dict[str, float]]:
    """Fit every id on ``runs``; ``tf+lstm`` from network seed ``seed``."""
    fitted, seconds = {}, {}
    for pid in ids:
        note = f" (seed {seed})" if pid == "tf+lstm" else ""
        _log(cfg, f"fitting {pid} on {label}{note} ...")
        params = {**cfg.predictor_params, "seed": seed} if pid == "tf+lstm" \
            else cfg.predictor_params
        t0 = time.perf_counter()
        fitted[pid] = _make(pid, params, cfg.verbose).fit(runs)
        seconds[pid] = time.perf_counter() - t0
        _log(cfg, f"  {pid}: {seconds[pid]:.1f} s")
    return fitted, seconds


def _setting(g: Sequence[Any]) -> tuple[int, float, int, bool]:
    """``(iterations, gain, advance, inverse)`` of a grid entry (``inverse`` defaults to off)."""
    return int(g[0]), float(g[1]), int(g[2]), bool(g[3]) if len(g) > 3 else False


def _tune_precomp(pred: Predictor, refs: Sequence[Reference], axis: Axis, seed: int,
                  grid: Sequence[Sequence[Any]]) -> tuple[int, float, int, bool]:
    """The pre-compensation setting with the smallest worst-case actual error on ``refs``
    (settings that need a transfer function are skipped for predictors without one)."""
    settings = [_setting(g) for g in grid]
    settings = [s for s in settings if not s[3] or hasattr(pred, "tf_")]
    scores = []
    for it, gain, adv, inv in settings:
        worst = max(simulate(axis, r, seed=seed + i, u_offset=precompensation_offset(
            pred, r, iterations=it, gain=gain, advance=adv, inverse=inv)).max_error
            for i, r in enumerate(refs))
        scores.append(worst)
    return settings[int(np.argmin(scores))]


class _Known(Predictor):
    """The measured run itself as a "prediction" (for the pre-compensation bound only)."""

    def __init__(self, run: SimulationResult, tf_source: Predictor) -> None:
        self._run = run
        self.tf_ = tf_source.tf_  # type: ignore[attr-defined]
        self.ts_ = float(run.t[1] - run.t[0])

    def get_params(self) -> dict[str, Any]:
        return {}

    def _fit(self, runs: list[Any], ts: float) -> None:
        raise NotImplementedError("_Known is built from a run, not fitted")

    def _predict_position(self, x_ref: np.ndarray) -> np.ndarray:
        return np.asarray(self._run.x_true, dtype=float)

    def _state(self) -> dict[str, Any]:
        raise NotImplementedError("_Known is not saved")

    def _set_state(self, state: dict[str, Any]) -> None:
        raise NotImplementedError("_Known is not loaded")


def _report(name: str, ref: Reference, test: SimulationResult, predictors: dict[str, Predictor],
            test_axis: Axis, friction_source: Predictor | None, precomp_ids: Sequence[str],
            tuned: dict[str, tuple[int, float, int, bool]]) -> TrajectoryReport:
    pred_err = {pid: test.x_true - p.predict(ref) for pid, p in predictors.items()}
    max_um = {pid: float(np.max(np.abs(e)) * 1e6) for pid, e in pred_err.items()}
    if friction_source is not None and hasattr(friction_source, "v_break_"):
        fe = extract_friction_error(friction_source.tf_, test.x_ref, test.x, ref.ts,  # type: ignore[attr-defined]
                                    friction_source.v_break_)  # type: ignore[attr-defined]
        fric, mask = fe.friction_error, fe.mask
    else:
        fric, mask = np.zeros_like(test.x_ref), np.zeros(test.x_ref.shape, dtype=bool)
    pre_err = {"none": test.error}
    settings = {}
    for pid in precomp_ids:
        if pid not in predictors:
            continue
        off = precompensation_offset(predictors[pid], ref)
        pre_err[pid] = simulate(test_axis, ref, seed=test.seed, u_offset=off).error
        if hasattr(predictors[pid], "tf_"):
            off = precompensation_offset(predictors[pid], ref, inverse=True)
            pre_err[f"{pid} inverse"] = simulate(test_axis, ref, seed=test.seed,
                                                 u_offset=off).error
        if pid in tuned and tuned[pid] not in ((1, 1.0, 0, False), (1, 1.0, 0, True)):
            it, gain, adv, inv = tuned[pid]
            off = precompensation_offset(predictors[pid], ref, iterations=it, gain=gain,
                                         advance=adv, inverse=inv)
            pre_err[f"{pid} tuned"] = simulate(test_axis, ref, seed=test.seed,
                                               u_offset=off).error
            settings[f"{pid} tuned"] = tuned[pid]
    if friction_source is not None and hasattr(friction_source, "tf_"):
        # a bound, not a predictor: the held-out run's own error, model-inverted through the
        # predictor's TF (what a perfect one-shot predictor could at best give)
        off = precompensation_offset(_Known(test, friction_source), ref, inverse=True)
        pre_err["oracle inverse"] = simulate(test_axis, ref, seed=test.seed,
                                             u_offset=off).error
    pre_max = {k: float(np.max(np.abs(v)) * 1e6) for k, v in pre_err.items()}
    return TrajectoryReport(name, ref.t, test.x_ref, test.error, fric, mask, pred_err, max_um,
                            pre_err, pre_max, settings)


def reproduce(config: ReproduceConfig | None = None) -> ReproduceResult:
    """Run the paper's experiment on the default axis; see the module docstring.

    Parameters
    ----------
    config : ReproduceConfig, optional
        Defaults reproduce the numbers in ``docs/reproduction.md``.

    Returns
    -------
    ReproduceResult
    """
    cfg = config or ReproduceConfig()
    if not isinstance(cfg, ReproduceConfig):
        raise TypeError(f"config={cfg!r}: expected a ReproduceConfig")
    t_start = time.perf_counter()
    ids = list(dict.fromkeys(["tf", "tf+lstm", *cfg.predictors]))
    for pid in ids:
        predictor_registry.spec(pid)  # unknown ids fail before any work
    axis = Axis()
    train_axis = axis.with_effects(quantization=cfg.quantization, noise_std=cfg.train_noise_std)
    test_axis = axis.with_effects(quantization=cfg.quantization, noise_std=cfg.test_noise_std)
    refs = {name: make_trajectory(name) for name in TRAJECTORIES}
    train = [simulate(train_axis, refs[n], seed=cfg.train_seed + i)
             for i, n in enumerate(TRAJECTORIES)]
    test = {n: simulate(test_axis, refs[n], seed=cfg.test_seed + i)
            for i, n in enumerate(TRAJECTORIES)}
    n_train = sum(r.t.shape[0] for r in train)
    _log(cfg, f"training runs: {', '.join(TRAJECTORIES)} ({n_train} samples, noise "
              f"{cfg.train_noise_std * 1e6:g} um, seeds {cfg.train_seed}..); held-out runs: "
              f"noise {cfg.test_noise_std * 1e6:g} um, seeds {cfg.test_seed}..")
    bv = identify_v_break_multi([r.x_ref for r in train], [r.x for r in train], axis.controller.ts)
    _log(cfg, f"v_break = {bv.v_break * 1e3:.3f} mm/s (x_break {bv.x_break * 1e6:.2f} um, "
              f"{len(bv.breakaways)} breakaways)")
    fitted, seconds = _fit_all(ids, train, cfg, "M-serial + curve", cfg.seeds[0])
    lstm = fitted["tf+lstm"]
    precomp_ids = [pid for pid in ids if pid != "tf+stribeck"]
    train_refs = [refs[n] for n in TRAJECTORIES]
    tuned = {pid: _tune_precomp(fitted[pid], train_refs, train_axis, cfg.train_seed + 50,
                                cfg.precomp_grid) for pid in precomp_ids}
    _log(cfg, "pre-compensation settings (iterations, gain, advance, inverse) chosen on the "
              f"training references: {tuned}")
    reports = {n: _report(n, refs[n], test[n], fitted, test_axis, lstm, precomp_ids, tuned)
               for n in TRAJECTORIES}
    # the best registered predictor: largest worst-case TF / predictor ratio
    candidates = [pid for pid in ids if pid != "tf"]
    best = max(candidates, key=lambda pid: min(reports[n].ratio(pid) for n in TRAJECTORIES))
    # cross-trajectory: trained without the curve
    cross_refs = [make_trajectory(tid, **params) for tid, params in cfg.cross_training]
    cross_train = [simulate(train_axis, r, seed=cfg.train_seed + 10 + i)
                   for i, r in enumerate(cross_refs)]
    cross_ids = list(dict.fromkeys(["tf", "tf+lstm", best]))
    cross_fitted, _ = _fit_all(cross_ids, cross_train, cfg,
                               " + ".join(t for t, _ in cfg.cross_training), cfg.seeds[0])
    cross_tuned = {pid: _tune_precomp(cross_fitted[pid], cross_refs, train_axis,
                                      cfg.train_seed + 60, cfg.precomp_grid)
                   for pid in cross_ids if pid != "tf+stribeck"}
    cross = _report("curve (cross)", refs["curve"], test["curve"], cross_fitted, test_axis,
                    cross_fitted["tf+lstm"], cross_ids, cross_tuned)
    # the spread over network seeds: tf+lstm alone, refitted on the same training runs
    tf_max = {n: reports[n].max_um["tf"] for n in TRAJECTORIES}
    seeds = [SeedResult.from_reports(cfg.seeds[0], reports, tf_max, seconds["tf+lstm"])]
    for seed in cfg.seeds[1:]:
        one, sec = _fit_all(["tf+lstm"], train, cfg, "M-serial + curve", seed)
        one_tuned = {"tf+lstm": _tune_precomp(one["tf+lstm"], train_refs, train_axis,
                                              cfg.train_seed + 50, cfg.precomp_grid)}
        seed_reports = {n: _report(n, refs[n], test[n], one, test_axis, None, ["tf+lstm"],
                                   one_tuned) for n in TRAJECTORIES}
        seeds.append(SeedResult.from_reports(seed, seed_reports, tf_max, sec["tf+lstm"]))
        r = seeds[-1]
        _log(cfg, f"tf+lstm seed {seed}: {r.ratio['m_serial']:.1f}x M-serial, "
                  f"{r.ratio['curve']:.1f}x curve, pre-compensation cut "
                  f"{r.precomp_cut['best']:.0%} (best of one-shot, model-inverse, tuned)")
    tf_pred = fitted["tf"]
    return ReproduceResult(
        tf_num=[float(c) for c in tf_pred.tf_.num[0][0]],  # type: ignore[attr-defined]
        tf_den=[float(c) for c in tf_pred.tf_.den[0][0]],  # type: ignore[attr-defined]
        tf_lstm_num=[float(c) for c in lstm.tf_.num[0][0]],  # type: ignore[attr-defined]
        tf_lstm_den=[float(c) for c in lstm.tf_.den[0][0]],  # type: ignore[attr-defined]
        v_break_mm_s=bv.v_break * 1e3,
        train_seconds=seconds["tf+lstm"],
        fit_seconds=seconds,
        trajectories=reports,
        cross=cross,
        best=best,
        config=cfg,
        n_train_samples=n_train,
        seeds=seeds,
        seconds=time.perf_counter() - t_start,
    )


# -- outputs --------------------------------------------------------------------------------
def write_json(result: ReproduceResult, path: str | os.PathLike[str]) -> Path:
    """Write ``result.to_json()`` to ``path`` atomically; return the path."""
    path = Path(path)
    atomic_write(path, json.dumps(result.to_json(), indent=2) + "\n")
    return path


def _poly(coeffs: Sequence[float]) -> str:
    n = len(coeffs) - 1
    terms = []
    for i, c in enumerate(coeffs):
        p = n - i
        s = "" if p == 0 else ("s" if p == 1 else f"s^{p}")
        terms.append(f"{c:.4g}{(' ' + s) if s else ''}")
    return " + ".join(terms)


def _description(pid: str) -> str:
    return predictor_registry.spec(pid).description or pid


def format_report(result: ReproduceResult) -> str:
    """Our numbers beside the paper's, as printed by ``fricbench reproduce``."""
    ms, cu = result.trajectories["m_serial"], result.trajectories["curve"]
    lines = [
        "fricbench reproduce: Wang & Zhang (2023) on the default axis, held-out runs",
        f"TF (TF-only):  G(s) = ({_poly(result.tf_num)}) / ({_poly(result.tf_den)})",
        f"TF in TF+LSTM: G(s) = ({_poly(result.tf_lstm_num)}) / ({_poly(result.tf_lstm_den)})",
        f"v_break = {result.v_break_mm_s:.2f} mm/s (paper {PAPER['v_break_mm_s']} mm/s); "
        f"TF+LSTM fit {result.train_seconds:.1f} s on {result.n_train_samples} samples",
        "",
        f"{'max error [um]':32s}{'M-serial':>10s}{'paper':>8s}{'curve':>10s}{'paper':>8s}",
    ]

    def row(label: str, a: float, pa: float | None, b: float, pb: float | None) -> str:
        f = (lambda z: f"{z:8.1f}" if z is not None else f"{'-':>8s}")
        return f"{label:32s}{a:10.2f}{f(pa)}{b:10.2f}{f(pb)}"

    pm, pc = PAPER["m_serial"], PAPER["curve"]
    lines.append(row("actual tracking error", ms.tracking_max_um, pm["tracking_max_um"],
                     cu.tracking_max_um, pc["tracking_max_um"]))
    lines.append(row("TF prediction error", ms.max_um["tf"], pm["tf_max_um"], cu.max_um["tf"],
                     pc["tf_max_um"]))
    lines.append(row("TF+LSTM prediction error", ms.max_um["tf+lstm"], pm["tf_lstm_max_um"],
                     cu.max_um["tf+lstm"], pc["tf_lstm_max_um"]))
    lines.append(f"{'  ratio TF / TF+LSTM':32s}{ms.ratio('tf+lstm'):9.1f}x"
                 f"{pm['tf_max_um'] / pm['tf_lstm_max_um']:7.1f}x{cu.ratio('tf+lstm'):9.1f}x"
                 f"{pc['tf_max_um'] / pc['tf_lstm_max_um']:7.1f}x")
    for pid in ms.max_um:
        if pid in ("tf", "tf+lstm"):
            continue
        lines.append(row(f"{pid} prediction error", ms.max_um[pid], None, cu.max_um[pid], None)
                     + f"   ({ms.ratio(pid):.1f}x, {cu.ratio(pid):.1f}x)")
    lines += ["", "pre-compensation x_r' = x_r + e_pred: actual max tracking error [um]"
                  f"{'M-serial':>14s}{'curve':>13s}"]
    for key in ms.precomp_max_um:
        label = key if key == "none" or key.endswith(" tuned") else f"{key} (one-shot)"
        if key.endswith(" inverse"):
            label = f"{key[:-8]} model-inverse (one-shot)"
        if key == "oracle inverse":
            label = "perfect prediction (run's own error), model-inverse"
        if key.endswith(" tuned"):
            it, gain, adv, inv = ms.precomp_settings[key]
            label = f"{key} ({it} it, gain {gain:g}, adv {adv}{', inverse' if inv else ''})"
        cut_m = 1 - ms.precomp_max_um[key] / ms.precomp_max_um["none"]
        cut_c = (1 - cu.precomp_max_um[key] / cu.precomp_max_um["none"]
                 if key in cu.precomp_max_um else float("nan"))
        cu_v = cu.precomp_max_um.get(key, float("nan"))
        lines.append(f"  {label:52s}{ms.precomp_max_um[key]:8.2f} ({cut_m:+4.0%})"
                     f"{cu_v:9.2f} ({cut_c:+4.0%})")
    cr = result.cross
    lines += ["", f"cross-trajectory: trained on "
                  f"{' + '.join(t for t, _ in result.config.cross_training)}, evaluated on the "
                  "curve"]
    for pid, v in cr.max_um.items():
        extra = "" if pid == "tf" else f"   ({cr.ratio(pid):.1f}x)"
        lines.append(f"  {pid + ' prediction error':30s}{v:10.2f}{extra}")
    for key, v in cr.precomp_max_um.items():
        lines.append(f"  {'precomp ' + key:30s}{v:10.2f}")
    cuts = _lstm_cuts(ms)
    cut_o = (1 - ms.precomp_max_um["oracle inverse"] / ms.precomp_max_um["none"]
             if "oracle inverse" in ms.precomp_max_um else float("nan"))
    b_ms, b_cu = ms.ratio(result.best), cu.ratio(result.best)
    best_keys = [k for k in (result.best, f"{result.best} inverse", f"{result.best} tuned")
                 if k in ms.precomp_max_um]
    best_cut = max((1 - ms.precomp_max_um[k] / ms.precomp_max_um["none"] for k in best_keys),
                   default=float("nan"))

    def ok(flag: bool) -> str:
        return "met" if flag else "MISSED"

    seeds = [r.seed for r in result.seeds]
    sp, tg = result.seed_spread(), result.targets()

    def ratio_row(label: str, key: str) -> str:
        per = " ".join(f"{v:.1f}" for v in result._values(key))
        return (f"  {label:38s}{sp[key]['median']:6.1f}x  [{sp[key]['min']:.1f} - "
                f"{sp[key]['max']:.1f}]   per seed: {per}")

    def cut_row(label: str, key: str) -> str:
        per = " ".join(f"{v:.0%}" for v in result._values(key))
        return (f"  {label:38s}{sp[key]['median']:6.0%}   [{sp[key]['min']:.0%} - "
                f"{sp[key]['max']:.0%}]   per seed: {per}")

    n = len(seeds)
    lines += [
        "",
        f"TF+LSTM over {n} network seed{'s' if n > 1 else ''} "
        f"({', '.join(map(str, seeds))}; same training and held-out runs): "
        "median [min - max]",
        ratio_row("ratio TF / TF+LSTM, M-serial", "m_serial_ratio"),
        ratio_row("ratio TF / TF+LSTM, curve", "curve_ratio"),
        cut_row("M-serial pre-compensation, one-shot", "m_serial_precomp_cut_one_shot"),
        cut_row("  model-inverse", "m_serial_precomp_cut_inverse"),
        cut_row("  tuned on training references", "m_serial_precomp_cut_tuned"),
        cut_row("  best of the three", "m_serial_precomp_cut_best"),
        f"  fit time per seed: {', '.join(f'{r.fit_seconds:.0f}' for r in result.seeds)} s; "
        f"whole reproduction {result.seconds:.0f} s",
    ]

    def target_row(label: str, key: str, fmt: str) -> str:
        t = tg[key]
        unit = "x" if fmt.endswith("f") else ""
        return (f"  {label}: median {format(t['median'], fmt)}{unit} [{format(t['min'], fmt)} - "
                f"{format(t['max'], fmt)}{unit}], {t['met_by_seeds']} of {n} seeds: "
                f"{ok(t['met'])}")

    lines += [
        "",
        f"targets (held-out runs; judged on the median over the {n} seed"
        f"{'s' if n > 1 else ''}):",
        target_row("TF+LSTM <= TF/5 on M-serial", "m_serial_ratio", ".1f"),
        target_row("TF+LSTM <= TF/3 on curve   ", "curve_ratio", ".1f"),
        target_row("TF+LSTM pre-compensation cuts M-serial max error >= 70 % (best of one-shot,"
                   " model-inverse, tuned)", "m_serial_precomp_cut", ".0%"),
        f"  seed {seeds[0]} alone (the tables above): {ms.ratio('tf+lstm'):.1f}x M-serial, "
        f"{cu.ratio('tf+lstm'):.1f}x curve, cut {cuts['one_shot']:.0%} one-shot, "
        f"{cuts['tuned']:.0%} tuned, {cuts['inverse']:.0%} model-inverse (perfect prediction, "
        f"model-inverse: {cut_o:.0%})",
        f"  the same with {result.best} ({_description(result.best)}, one seed): "
        f"{best_cut:.0%} (best of one-shot, model-inverse, tuned) "
        f"{ok(best_cut >= TARGETS['m_serial_precomp_cut'])}",
        f"  best predictor {result.best} (one seed): {b_ms:.1f}x M-serial, {b_cu:.1f}x curve, "
        f">= 10x on both: {ok(min(b_ms, b_cu) >= TARGETS['beat_paper_ratio'])}",
    ]
    return "\n".join(lines)


def plot_figures(result: ReproduceResult, directory: str | os.PathLike[str]) -> list[Path]:
    """Counterparts of the paper's Figures 11-18, plus pre-compensation and cross-trajectory.

    Returns the written PNG paths.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    out_dir = Path(directory)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    um = 1e6

    def save(fig: Any, name: str) -> None:
        p = out_dir / name
        fig.tight_layout()
        fig.savefig(p, dpi=110)
        plt.close(fig)
        paths.append(p)

    figs = {"m_serial": (11, "M-serial linear trajectory"), "curve": (15, "curve")}
    for name, (n0, title) in figs.items():
        rep = result.trajectories[name]
        t = rep.t
        fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
        ax[0].plot(t, rep.x_ref * 1e3)
        ax[0].set_ylabel("reference [mm]")
        ax[0].set_title(f"Fig. {n0}: {title}, (a) reference position, (b) tracking error")
        ax[1].plot(t, rep.tracking_error * um, lw=0.8)
        ax[1].set_ylabel("tracking error [um]")
        ax[1].set_xlabel("time [s]")
        save(fig, f"fig{n0}_{name}_tracking.png")

        fig, ax = plt.subplots(figsize=(8, 3))
        ax.plot(t, rep.prediction_errors["tf"] * um, lw=0.8)
        ax.set_title(f"Fig. {n0 + 1}: {title}, prediction error of the TF "
                     f"(max {rep.max_um['tf']:.1f} um)")
        ax.set_ylabel("x - x_TF [um]")
        ax.set_xlabel("time [s]")
        save(fig, f"fig{n0 + 1}_{name}_tf_prediction_error.png")

        fig, ax = plt.subplots(figsize=(8, 3))
        ax.fill_between(t, 0, 1, where=rep.presliding, transform=ax.get_xaxis_transform(),
                        color="0.9", label="pre-sliding windows")
        ax.plot(t, rep.friction_error * um, lw=0.8, label="nonlinear friction error")
        ax.set_title(f"Fig. {n0 + 2}: {title}, nonlinear friction error (held-out run)")
        ax.set_ylabel("[um]")
        ax.set_xlabel("time [s]")
        ax.legend(loc="upper right", fontsize=8)
        save(fig, f"fig{n0 + 2}_{name}_friction_error.png")

        fig, ax = plt.subplots(figsize=(8, 3))
        ax.plot(t, rep.prediction_errors["tf"] * um, lw=0.6, color="0.7", label="TF")
        ax.plot(t, rep.prediction_errors["tf+lstm"] * um, lw=0.8,
                label=f"TF+LSTM (max {rep.max_um['tf+lstm']:.1f} um)")
        if result.best != "tf+lstm":
            ax.plot(t, rep.prediction_errors[result.best] * um, lw=0.8,
                    label=f"{result.best} (max {rep.max_um[result.best]:.1f} um)")
        ax.set_title(f"Fig. {n0 + 3}: {title}, prediction error of the tracking error")
        ax.set_ylabel("x - x_pred [um]")
        ax.set_xlabel("time [s]")
        ax.legend(loc="upper right", fontsize=8)
        save(fig, f"fig{n0 + 3}_{name}_tf_lstm_prediction_error.png")

        fig, ax = plt.subplots(figsize=(8, 3))
        for key, err in rep.precomp_errors.items():
            if key not in ("none", "tf", "tf+lstm", "tf+lstm tuned", f"{result.best} tuned"):
                continue
            ax.plot(t, err * um, lw=0.7, label=f"{key} (max {rep.precomp_max_um[key]:.1f} um)")
        ax.set_title(f"{title}: actual tracking error with pre-compensation x_r + e_pred")
        ax.set_ylabel("tracking error [um]")
        ax.set_xlabel("time [s]")
        ax.legend(loc="upper right", fontsize=7)
        save(fig, f"precomp_{name}.png")

    cr = result.cross
    fig, ax = plt.subplots(figsize=(8, 3))
    for pid, err in cr.prediction_errors.items():
        ax.plot(cr.t, err * um, lw=0.7, label=f"{pid} (max {cr.max_um[pid]:.1f} um)")
    ax.set_title("curve, predicted by predictors trained without it")
    ax.set_ylabel("x - x_pred [um]")
    ax.set_xlabel("time [s]")
    ax.legend(loc="upper right", fontsize=8)
    save(fig, "cross_curve_prediction_error.png")
    return paths
