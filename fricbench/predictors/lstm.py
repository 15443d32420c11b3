"""``tf+lstm``: the paper's combined model, TF prediction plus an LSTM friction-error model.

Training (paper, Sec. 3.3 and Fig. 9), for runs ``(x_ref, x)``:

1. identify the break velocity ``v_break`` (:func:`fricbench.sysid.identify_v_break_multi`),
2. fit the transfer function ``G`` outside the pre-sliding windows,
3. TF residual ``r = x - G x_ref``; the nonlinear friction error is ``r`` inside the windows
   (``target="friction_error"``, the paper) or the whole residual (``target="residual"``),
4. train a recurrent network on reference features (velocity and acceleration for the paper's
   ``features="va"``) to output that error.

Prediction for a new reference: ``x_pred = G x_ref + net(features(x_ref))``.

With ``base="greybox"`` the network corrects the identified closed loop of
:class:`fricbench.predictors.greybox.GreyBoxPredictor` instead of ``G``: the residual is
``r = x - greybox(x_ref)`` and ``x_pred = greybox(x_ref) + net(features(x_ref))``. The grey
box carries the stick-slip the loop and its Stribeck friction explain; the network learns
what the grey box's structure lacks (pre-sliding, backlash, ...). ``G`` is still fitted, for
model-inverse pre-compensation.

Network and training choices (the paper gives none; ours, documented):

* one LSTM (or GRU) layer of ``hidden_size`` units and a linear read-out, sequence to sequence;
* inputs normalised to zero mean and unit variance over the training samples, the output
  scaled by the target's standard deviation;
* *sequence windows*: each run is preceded by ``lead`` samples at rest and cut into windows
  of ``window`` samples. The first window starts at the record's start, so the network's state
  is fresh where the axis's is (at rest, controller integrator empty: the first start of a run
  differs from every later one, and a warm-up on padded rest would hide that); every later
  window repeats ``burn_in`` samples whose outputs only warm the state up and are not scored.
  The scored parts tile the data exactly once. Prediction cuts the reference the same way and
  stitches the scored parts, so the network sees exactly the contexts it was trained on;
* validation split: every ``round(1 / validation_fraction)``-th window, spread over all runs;
  Adam with gradient clipping, learning rate halved when the validation loss stalls for 5
  epochs, early stopping after ``patience`` epochs without improvement, best weights kept;
* *restarts*: an LSTM trained on a few dozen windows lands in quite different minima from one
  seed to the next (measured on the paper's experiment: held-out max prediction errors from
  2.3 to 8 um over seeds). ``n_init`` candidates are trained for ``screen_epochs`` each (in
  ``n_jobs`` threads), and the one with the lowest validation loss goes on training, the
  scikit-learn ``n_init`` idiom with a cheap screening round;
* deterministic on CPU for a given ``seed``: ``torch.manual_seed``, deterministic algorithms
  and ``n_threads`` threads during ``fit``/``predict`` (the previous global settings are
  restored afterwards).
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from fricbench._validation import check_choice, check_int, check_positive, check_range
from fricbench.predictors.base import Predictor, Run
from fricbench.predictors.features import FEATURE_SETS, feature_names, reference_features
from fricbench.predictors.greybox import GreyBoxPredictor
from fricbench.predictors.tf import check_tf_orders, fit_linear_part, tf_from_state, tf_state
from fricbench.sysid.friction_error import identify_v_break_multi, presliding_mask
from fricbench.sysid.tf_fit import simulate_tf

__all__ = ["TFLSTMPredictor", "SequenceNet"]

TARGETS = ("friction_error", "residual")
BASES = ("tf", "greybox")
CELLS = ("lstm", "gru")

#: Held while a candidate seeds torch's global generator and draws its initial weights from
#: it, so that fits running side by side in threads of one process cannot interleave there.
_GLOBAL_RNG_LOCK = threading.Lock()


class SequenceNet(torch.nn.Module):
    """Recurrent layer(s) and a linear read-out: ``(N, L, F) -> (N, L)``."""

    def __init__(self, n_inputs: int, hidden_size: int, num_layers: int, cell: str) -> None:
        super().__init__()
        rnn = torch.nn.LSTM if cell == "lstm" else torch.nn.GRU
        self.rnn = rnn(n_inputs, hidden_size, num_layers=num_layers, batch_first=True)
        self.head = torch.nn.Linear(hidden_size, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h, _ = self.rnn(x)
        return self.head(h).squeeze(-1)


#: Fits inside :func:`_torch_determinism` and the torch settings to restore after the last.
_SETTINGS_LOCK = threading.Lock()
_SETTINGS: dict[str, Any] = {"active": 0, "threads": 1, "deterministic": False}


@contextlib.contextmanager
def _torch_determinism(seed: int, n_threads: int) -> Iterator[None]:
    """Seed torch, force deterministic kernels and a fixed thread count; restore afterwards.

    The thread count and the deterministic flag are process-wide: with fits side by side in
    threads, only the last one to leave restores them (restoring while another fit trains
    would change its kernels, hence its numbers).
    """
    with _SETTINGS_LOCK:
        if _SETTINGS["active"] == 0:
            _SETTINGS["threads"] = torch.get_num_threads()
            _SETTINGS["deterministic"] = torch.are_deterministic_algorithms_enabled()
        _SETTINGS["active"] += 1
        torch.set_num_threads(n_threads)
        torch.use_deterministic_algorithms(True)
        with _GLOBAL_RNG_LOCK:
            torch.manual_seed(seed)
    try:
        yield
    finally:
        with _SETTINGS_LOCK:
            _SETTINGS["active"] -= 1
            if _SETTINGS["active"] == 0:
                torch.set_num_threads(_SETTINGS["threads"])
                torch.use_deterministic_algorithms(_SETTINGS["deterministic"])


def _masked_mse(out: torch.Tensor, y: torch.Tensor, w: torch.Tensor) -> torch.Tensor:
    """Mean of ``(out - y)^2`` over the scored samples (``w`` is 1 there, 0 on the warm-up)."""
    return (w * (out - y) ** 2).sum() / w.sum()


def _windows(n: int, window: int, burn_in: int, lead: int) -> list[tuple[int, int]]:
    """``(start, first scored index)`` of the windows cut from a padded record of ``n`` samples.

    The record begins with ``lead`` samples of rest. The first window starts at the record's
    first sample (the network state is fresh there, as the axis's controller state is at the
    start of a run) and is scored from ``lead`` on; every later window repeats ``burn_in``
    samples of warm-up, so the scored parts tile ``[lead, n)`` exactly once (the last window is
    aligned to the end and scored from where the previous one stopped). A record shorter than
    ``window`` is one window of its own length.
    """
    if n <= window:
        return [(0, lead)]
    out = [(0, lead)]
    step = window - burn_in
    s = step
    while s + window < n:
        out.append((s, burn_in))
        s += step
    out.append((n - window, s + burn_in - (n - window)))
    return out


@dataclass(frozen=True)
class _Data:
    """Training and validation windows: inputs, targets and scored-sample masks."""

    x_tr: torch.Tensor
    y_tr: torch.Tensor
    w_tr: torch.Tensor
    x_va: torch.Tensor
    y_va: torch.Tensor
    w_va: torch.Tensor


class _Candidate:
    """One network in training, with its optimiser, schedule and early-stopping state, so
    that training can stop after the screening epochs and resume where it left off."""

    def __init__(self, owner: TFLSTMPredictor, seed: int, data: _Data) -> None:
        self.owner, self.data = owner, data
        # the module initialisers draw from torch's global generator: seed and draw in one go
        with _GLOBAL_RNG_LOCK:
            torch.manual_seed(seed)
            self.net = owner._new_net()
        self.opt = torch.optim.Adam(self.net.parameters(), lr=owner.learning_rate)
        self.sched = torch.optim.lr_scheduler.ReduceLROnPlateau(self.opt, factor=0.5,
                                                                patience=5)
        self.gen = torch.Generator().manual_seed(seed)
        self.best_val = math.inf
        self.best_state: dict[str, torch.Tensor] | None = None
        self.stale = 0
        self.history: list[tuple[int, float, float]] = []

    @property
    def stopped(self) -> bool:
        return self.stale >= self.owner.patience

    def train(self, n_epochs: int, t0: float, label: str = "") -> None:
        """Up to ``n_epochs`` more epochs (fewer if early stopping triggers)."""
        d, o = self.data, self.owner
        for _ in range(n_epochs):
            if self.stopped:
                return
            epoch = len(self.history) + 1
            self.net.train()
            perm = torch.randperm(len(d.x_tr), generator=self.gen)
            total, count = 0.0, 0
            for i in range(0, len(perm), o.batch_size):
                idx = perm[i:i + o.batch_size]
                self.opt.zero_grad()
                loss = _masked_mse(self.net(d.x_tr[idx]), d.y_tr[idx], d.w_tr[idx])
                loss.backward()
                torch.nn.utils.clip_grad_norm_(self.net.parameters(), 1.0)
                self.opt.step()
                total += float(loss.detach()) * len(idx)
                count += len(idx)
            self.net.eval()
            with torch.no_grad():
                val = float(_masked_mse(self.net(d.x_va), d.y_va, d.w_va))
            self.sched.step(val)
            self.history.append((epoch, total / count, val))
            if val < self.best_val * (1.0 - 1e-4):
                self.best_val, self.stale = val, 0
                self.best_state = {k: v.detach().clone()
                                   for k, v in self.net.state_dict().items()}
            else:
                self.stale += 1
            if o.verbose and (epoch % o.verbose == 0 or epoch == 1):
                o._log(f"{label}epoch {epoch:4d}  train {total / count:.4f}  val {val:.4f}  "
                       f"best {self.best_val:.4f}  {time.perf_counter() - t0:6.1f} s")

    def finish(self) -> SequenceNet:
        """The network with its best validation weights, in eval mode."""
        if self.best_state is not None:
            self.net.load_state_dict(self.best_state)
        self.net.eval()
        return self.net


class TFLSTMPredictor(Predictor):
    """TF prediction plus a recurrent model of the friction error (the paper's TF+LSTM).

    Parameters
    ----------
    features : {"va", "physical"}, optional
        Input features (:mod:`fricbench.predictors.features`); ``"va"`` is the paper's.
    target : {"friction_error", "residual"}, optional
        What the network learns: the base model's residual inside the pre-sliding windows
        (paper) or the whole residual.
    base : {"tf", "greybox"}, optional
        The model the network corrects: the transfer function (paper) or the identified
        closed loop (``greybox``).
    cell : {"lstm", "gru"}, optional
        Recurrent cell.
    hidden_size, num_layers : int, optional
        Size of the recurrent part.
    window, burn_in : int, optional
        Sequence window length and its unscored warm-up, samples (``burn_in`` should cover the
        longest dwell the network must remember across; 0.3 s at 1 ms by default).
    lead : int, optional
        Samples at rest put in front of every record (for the difference stencils of the
        features); the first window is scored from there on.
    batch_size : int, optional
        Windows per gradient step.
    learning_rate : float, optional
        Adam step size.
    max_epochs, patience : int, optional
        Epoch budget and early-stopping patience.
    validation_fraction : float, optional
        Share of windows held out for early stopping.
    seed : int, optional
        Seed of the weight initialisation and the batch order (of the first candidate; the
        others derive theirs from it through ``numpy.random.SeedSequence``).
    n_init : int, optional
        Candidate networks trained from different seeds; 1 trains one network.
    screen_epochs : int, optional
        Epochs each candidate trains before the best one (validation loss) is kept.
    n_jobs : int, optional
        Threads that train candidates side by side during screening (results do not depend
        on it).
    n_threads : int, optional
        Torch threads during fit and predict (fixed for determinism). One by default: the
        matrices of a small LSTM are too small to gain from more, and on a busy machine extra
        threads spin against each other (measured: 40x slower at two threads under load).
    n_poles, n_zeros, dc_gain : optional
        Transfer-function structure (:class:`fricbench.predictors.tf.TFPredictor`).
    window_pre, window_post : float, optional
        Widening of the pre-sliding windows, s (:func:`fricbench.sysid.presliding_mask`).
    verbose : int, optional
        Print training progress every ``verbose`` epochs (0: silent).

    Attributes
    ----------
    tf_ : control.TransferFunction
        ``G(s)`` fitted outside the pre-sliding windows.
    base_ : GreyBoxPredictor or None
        The fitted closed loop (``base="greybox"``).
    v_break_ : float
        Identified break velocity, m/s.
    net_ : SequenceNet
        The trained network.
    history_ : list of tuple
        ``(epoch, train_loss, val_loss)`` per epoch of the kept network (normalised units).
    candidate_val_losses_ : list of float
        Best validation loss of every candidate after screening (empty for ``n_init=1``).
    train_seconds_ : float
        Wall-clock time of the network training, s.
    """

    def __init__(
        self,
        features: str = "va",
        target: str = "friction_error",
        base: str = "tf",
        cell: str = "lstm",
        hidden_size: int = 48,
        num_layers: int = 1,
        window: int = 800,
        burn_in: int = 300,
        lead: int = 10,
        batch_size: int = 16,
        learning_rate: float = 5e-3,
        max_epochs: int = 300,
        patience: int = 40,
        validation_fraction: float = 0.15,
        seed: int = 0,
        n_threads: int = 1,
        n_poles: int = 3,
        n_zeros: int = 2,
        dc_gain: float | None = None,
        window_pre: float = 0.02,
        window_post: float = 0.1,
        n_init: int = 3,
        screen_epochs: int = 40,
        n_jobs: int = 2,
        verbose: int = 10,
    ) -> None:
        check_choice("features", features, FEATURE_SETS)
        check_choice("target", target, TARGETS)
        check_choice("base", base, BASES)
        check_choice("cell", cell, CELLS)
        check_int("hidden_size", hidden_size, 1, 4096)
        check_int("num_layers", num_layers, 1, 8)
        check_int("window", window, 2)
        check_int("burn_in", burn_in, 0)
        if burn_in >= window:
            raise ValueError(f"burn_in={burn_in!r}: expected fewer samples than window={window}")
        check_int("lead", lead, 0)
        if lead >= window:
            raise ValueError(f"lead={lead!r}: expected fewer samples than window={window}")
        check_int("batch_size", batch_size, 1)
        check_positive("learning_rate", learning_rate)
        check_int("max_epochs", max_epochs, 1)
        check_int("patience", patience, 1)
        check_range("validation_fraction", validation_fraction, 0.01, 0.5)
        check_int("seed", seed, 0)
        check_int("n_threads", n_threads, 1, 256)
        check_tf_orders(n_poles, n_zeros, dc_gain)
        check_range("window_pre", window_pre, 0.0, 10.0, "s")
        check_range("window_post", window_post, 0.0, 10.0, "s")
        check_int("n_init", n_init, 1, 100)
        check_int("screen_epochs", screen_epochs, 1)
        check_int("n_jobs", n_jobs, 1, 256)
        check_int("verbose", verbose, 0)
        self.features = features
        self.target = target
        self.base = base
        self.cell = cell
        self.hidden_size = hidden_size
        self.num_layers = num_layers
        self.window = window
        self.burn_in = burn_in
        self.lead = lead
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.max_epochs = max_epochs
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.seed = seed
        self.n_threads = n_threads
        self.n_poles = n_poles
        self.n_zeros = n_zeros
        self.dc_gain = dc_gain
        self.window_pre = window_pre
        self.window_post = window_post
        self.n_init = n_init
        self.screen_epochs = screen_epochs
        self.n_jobs = n_jobs
        self.verbose = verbose

    # -- helpers --------------------------------------------------------------------------------
    def _new_net(self) -> SequenceNet:
        return SequenceNet(len(feature_names(self.features)), self.hidden_size, self.num_layers,
                           self.cell)

    def _new_base(self) -> GreyBoxPredictor:
        return GreyBoxPredictor(n_poles=self.n_poles, n_zeros=self.n_zeros,
                                verbose=1 if self.verbose else 0)

    def _candidate_seeds(self) -> list[int]:
        """Torch seeds of the ``n_init`` candidates: ``seed`` itself, then derived ones."""
        extra = np.random.SeedSequence(self.seed).generate_state(self.n_init - 1)
        return [self.seed, *(int(v) for v in extra)]

    def _inputs(self, x_ref: np.ndarray, ts: float) -> np.ndarray:
        """Normalised features of ``x_ref`` preceded by ``lead`` samples at rest."""
        padded = np.concatenate([np.full(self.lead, x_ref[0]), x_ref])
        feats = reference_features(padded, ts, self.features, self.v_break_)
        return ((feats - self.feature_mean_) / self.feature_scale_).astype(np.float32)

    def _log(self, msg: str) -> None:
        if self.verbose:
            print(f"[{type(self).__name__}] {msg}", flush=True)

    # -- kernels --------------------------------------------------------------------------------
    def _series(self, runs: list[Run], ts: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Raw features and targets of every run, each preceded by ``lead`` samples at rest."""
        raw_x, raw_y = [], []
        for r in runs:
            res = r.x - self._base_position(r.x_ref, ts)
            if self.target == "friction_error":
                mask = presliding_mask(r.x_ref, ts, self.v_break_, pre=self.window_pre,
                                       post=self.window_post)
                res = np.where(mask, res, 0.0)
            padded = np.concatenate([np.full(self.lead, r.x_ref[0]), r.x_ref])
            raw_x.append(reference_features(padded, ts, self.features, self.v_break_))
            raw_y.append(np.concatenate([np.zeros(self.lead), res]))
        return raw_x, raw_y

    def _cut(self, raw_x: list[np.ndarray], raw_y: list[np.ndarray]
             ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Normalised windows of the series: inputs, targets and the scored-sample mask."""
        wins_x, wins_y, wins_m = [], [], []
        for fx, fy in zip(raw_x, raw_y, strict=True):
            nx = (fx - self.feature_mean_) / self.feature_scale_
            ny = fy / self.target_scale_
            n = fx.shape[0]
            if n < self.window:  # short run: rest appended, not scored
                nx = np.vstack([nx, np.repeat(nx[-1:], self.window - n, axis=0)])
                ny = np.concatenate([ny, np.zeros(self.window - n)])
            for s, first in _windows(n, self.window, self.burn_in, self.lead):
                scored = np.zeros(self.window)
                scored[first:min(self.window, n - s)] = 1.0
                wins_x.append(nx[s:s + self.window])
                wins_y.append(ny[s:s + self.window])
                wins_m.append(scored)
        return (torch.tensor(np.stack(wins_x), dtype=torch.float32),
                torch.tensor(np.stack(wins_y), dtype=torch.float32),
                torch.tensor(np.stack(wins_m), dtype=torch.float32))

    def _base_position(self, x_ref: np.ndarray, ts: float) -> np.ndarray:
        """Position predicted by the model the network corrects."""
        if self.base_ is not None:
            return self.base_._predict_position(x_ref)
        return simulate_tf(self.tf_, x_ref, ts)

    def _fit(self, runs: list[Run], ts: float) -> None:
        bv = identify_v_break_multi([r.x_ref for r in runs], [r.x for r in runs], ts)
        self.v_break_ = bv.v_break
        self.tf_ = fit_linear_part(runs, ts, self.n_poles, self.n_zeros, self.dc_gain,
                                   v_break=bv.v_break, pre=self.window_pre,
                                   post=self.window_post)
        self.base_ = None
        if self.base == "greybox":
            self.base_ = self._new_base().fit(runs)
        raw_x, raw_y = self._series(runs, ts)
        all_x = np.vstack(raw_x)
        self.feature_mean_ = all_x.mean(axis=0)
        scale = all_x.std(axis=0)
        self.feature_scale_ = np.where(scale > 0, scale, 1.0)
        y_std = float(np.concatenate(raw_y).std())
        self.target_scale_ = y_std if y_std > 0 else 1.0
        x_all, y_all, m_all = self._cut(raw_x, raw_y)
        every = max(2, int(round(1.0 / self.validation_fraction)))
        is_val = torch.tensor([(i % every) == every // 2 for i in range(len(x_all))])
        if not bool(is_val.any()) or bool(is_val.all()):
            is_val = torch.zeros(len(x_all), dtype=torch.bool)
            is_val[-1] = len(x_all) > 1
        x_tr, y_tr, w_tr = x_all[~is_val], y_all[~is_val], m_all[~is_val]
        x_va, y_va, w_va = ((x_all[is_val], y_all[is_val], m_all[is_val])
                            if bool(is_val.any()) else (x_tr, y_tr, w_tr))
        self._log(f"v_break {bv.v_break * 1e3:.3f} mm/s; {sum(len(r.t) for r in runs)} samples,"
                  f" {len(x_tr)} training and {len(x_va)} validation windows of {self.window}")
        data = _Data(x_tr, y_tr, w_tr, x_va, y_va, w_va)
        t0 = time.perf_counter()
        with _torch_determinism(self.seed, self.n_threads):
            cands = [_Candidate(self, seed, data) for seed in self._candidate_seeds()]
            if len(cands) > 1:
                screen = min(self.screen_epochs, self.max_epochs)
                # candidates are independent (own weights, optimiser, batch generator): one
                # Python thread each, torch ops release the GIL
                with ThreadPoolExecutor(max_workers=self.n_jobs) as pool:
                    list(pool.map(lambda i: cands[i].train(
                        screen, t0, f"candidate {i + 1}/{len(cands)} "), range(len(cands))))
                scores = [c.best_val for c in cands]
                self.candidate_val_losses_ = scores
                win = int(np.argmin(scores))
                self._log(f"screening ({screen} epochs): best validation losses "
                          f"{', '.join(f'{v:.4f}' for v in scores)}; continuing candidate "
                          f"{win + 1}")
                best = cands[win]
            else:
                best = cands[0]
                self.candidate_val_losses_ = []
            best.train(self.max_epochs - len(best.history), t0)
            net = best.finish()
        self.train_seconds_ = time.perf_counter() - t0
        history = best.history
        self._log(f"done: {len(history)} epochs, best val {best.best_val:.4f}, "
                  f"{self.train_seconds_:.1f} s")
        self.net_ = net
        self.history_ = history
        self.n_epochs_ = len(history)

    def predict_friction_error(self, x_ref: np.ndarray) -> np.ndarray:
        """The network's output alone (predicted friction error or residual), m.

        ``x_ref`` is a validated 1-D reference at ``ts_``; ``predict`` is the usual entry.
        """
        self._check_fitted()
        feats = self._inputs(np.asarray(x_ref, dtype=float), self.ts_)
        n = feats.shape[0]
        cuts = _windows(n, self.window, self.burn_in, self.lead)
        length = min(n, self.window)
        with _torch_determinism(self.seed, self.n_threads), torch.no_grad():
            out = self.net_(torch.from_numpy(np.stack([feats[s:s + length]
                                                       for s, _ in cuts]))).double().numpy()
        y = np.zeros(n)
        for (s, first), o in zip(cuts, out, strict=True):
            y[s + first:s + length] = o[first:]
        return y[self.lead:] * self.target_scale_

    def _predict_position(self, x_ref: np.ndarray) -> np.ndarray:
        return self._base_position(x_ref, self.ts_) + self.predict_friction_error(x_ref)

    # -- persistence ----------------------------------------------------------------------------
    def _state(self) -> dict[str, torch.Tensor]:
        state = tf_state(self.tf_)
        state["v_break_"] = torch.tensor(self.v_break_, dtype=torch.float64)
        state["feature_mean_"] = torch.tensor(self.feature_mean_, dtype=torch.float64)
        state["feature_scale_"] = torch.tensor(self.feature_scale_, dtype=torch.float64)
        state["target_scale_"] = torch.tensor(self.target_scale_, dtype=torch.float64)
        for k, v in self.net_.state_dict().items():
            state[f"net.{k}"] = v.detach().clone()
        if self.base_ is not None:
            for k, v in self.base_._state().items():
                state[f"base.{k}"] = v
            state["base.ts_"] = torch.tensor(self.base_.ts_, dtype=torch.float64)
        return state

    def _expected_shapes(self, state: dict[str, torch.Tensor]) -> dict[str, tuple[int, ...]]:
        n_feat = len(feature_names(self.features))
        shapes: dict[str, tuple[int, ...]] = {
            "tf_num": (self.n_zeros + 1,), "tf_den": (self.n_poles + 1,), "v_break_": (),
            "feature_mean_": (n_feat,), "feature_scale_": (n_feat,), "target_scale_": ()}
        with torch.device("meta"):  # shapes only: a file's config must not allocate memory
            net = self._new_net()
        for k, v in net.state_dict().items():
            shapes[f"net.{k}"] = tuple(v.shape)
        if self.base == "greybox":
            for k, shape in self._new_base()._expected_shapes(state).items():
                shapes[f"base.{k}"] = shape
            shapes["base.ts_"] = ()
        return shapes

    def _set_state(self, state: dict[str, torch.Tensor]) -> None:
        self.tf_ = tf_from_state(state)
        self.v_break_ = float(state["v_break_"])
        self.feature_mean_ = state["feature_mean_"].double().numpy().copy()
        self.feature_scale_ = state["feature_scale_"].double().numpy().copy()
        self.target_scale_ = float(state["target_scale_"])
        net = self._new_net()
        net.load_state_dict({k[4:]: v for k, v in state.items() if k.startswith("net.")})
        net.eval()
        self.net_ = net
        self.base_ = None
        if self.base == "greybox":
            base = self._new_base()
            base._set_state({k[5:]: v for k, v in state.items() if k.startswith("base.")})
            base.ts_ = float(state["base.ts_"])
            self.base_ = base
