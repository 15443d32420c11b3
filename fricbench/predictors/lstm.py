"""``tf+lstm``: the paper's combined model, TF prediction plus an LSTM friction-error model.

Training (paper, Sec. 3.3 and Fig. 9), for runs ``(x_ref, x)``:

1. identify the break velocity ``v_break`` (:func:`fricbench.sysid.identify_v_break_multi`),
2. fit the transfer function ``G`` outside the pre-sliding windows,
3. TF residual ``r = x - G x_ref``; the nonlinear friction error is ``r`` inside the windows
   (``target="friction_error"``, the paper) or the whole residual (``target="residual"``),
4. train a recurrent network on reference features (velocity and acceleration for the paper's
   ``features="va"``) to output that error.

Prediction for a new reference: ``x_pred = G x_ref + net(features(x_ref))``.

Network and training choices (the paper gives none; ours, documented):

* one LSTM (or GRU) layer of ``hidden_size`` units and a linear read-out, sequence to sequence;
* inputs normalised to zero mean and unit variance over the training samples, the output
  scaled by the target's standard deviation;
* *sequence windows*: the runs are cut into windows of ``window`` samples overlapping by
  ``burn_in`` samples; the first ``burn_in`` outputs of a window only warm the state up and are
  not scored, so the scored parts tile the data exactly once. Each run is preceded by
  ``burn_in`` samples at rest. Prediction cuts the reference the same way and stitches the
  scored parts, so the network sees exactly the context lengths it was trained on;
* validation split: every ``round(1 / validation_fraction)``-th window, spread over all runs;
  Adam with gradient clipping, learning rate halved when the validation loss stalls for 5
  epochs, early stopping after ``patience`` epochs without improvement, best weights kept;
* deterministic on CPU for a given ``seed``: ``torch.manual_seed``, deterministic algorithms
  and ``n_threads`` threads during ``fit``/``predict`` (the previous global settings are
  restored afterwards).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator

import numpy as np
import torch

from fricbench._validation import check_choice, check_int, check_positive, check_range
from fricbench.predictors.base import Predictor, Run
from fricbench.predictors.features import FEATURE_SETS, feature_names, reference_features
from fricbench.predictors.tf import check_tf_orders, fit_linear_part, tf_from_state, tf_state
from fricbench.sysid.friction_error import identify_v_break_multi, presliding_mask
from fricbench.sysid.tf_fit import simulate_tf

__all__ = ["TFLSTMPredictor", "SequenceNet"]

TARGETS = ("friction_error", "residual")
CELLS = ("lstm", "gru")


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


@contextlib.contextmanager
def _torch_determinism(seed: int, n_threads: int) -> Iterator[None]:
    """Seed torch, force deterministic kernels and a fixed thread count; restore afterwards."""
    prev_threads = torch.get_num_threads()
    prev_det = torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(n_threads)
    torch.use_deterministic_algorithms(True)
    torch.manual_seed(seed)
    try:
        yield
    finally:
        torch.set_num_threads(prev_threads)
        torch.use_deterministic_algorithms(prev_det)


def _window_starts(n: int, window: int, burn_in: int) -> list[int]:
    """Starts of windows of length ``window`` whose scored parts tile ``[burn_in, n)``."""
    step = window - burn_in
    starts = list(range(0, max(n - window, 0) + 1, step))
    if starts[-1] + window < n:
        starts.append(n - window)
    return starts


class TFLSTMPredictor(Predictor):
    """TF prediction plus a recurrent model of the friction error (the paper's TF+LSTM).

    Parameters
    ----------
    features : {"va", "physical"}, optional
        Input features (:mod:`fricbench.predictors.features`); ``"va"`` is the paper's.
    target : {"friction_error", "residual"}, optional
        What the network learns: the TF residual inside the pre-sliding windows (paper) or the
        whole residual.
    cell : {"lstm", "gru"}, optional
        Recurrent cell.
    hidden_size, num_layers : int, optional
        Size of the recurrent part.
    window, burn_in : int, optional
        Sequence window length and its unscored warm-up, samples (``burn_in`` should cover the
        longest dwell the network must remember across; 0.3 s at 1 ms by default).
    batch_size : int, optional
        Windows per gradient step.
    learning_rate : float, optional
        Adam step size.
    max_epochs, patience : int, optional
        Epoch budget and early-stopping patience.
    validation_fraction : float, optional
        Share of windows held out for early stopping.
    seed : int, optional
        Seed of the weight initialisation and the batch order.
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
    v_break_ : float
        Identified break velocity, m/s.
    net_ : SequenceNet
        The trained network.
    history_ : list of tuple
        ``(epoch, train_loss, val_loss)`` per epoch (normalised units).
    train_seconds_ : float
        Wall-clock time of the network training, s.
    """

    def __init__(
        self,
        features: str = "va",
        target: str = "friction_error",
        cell: str = "lstm",
        hidden_size: int = 48,
        num_layers: int = 1,
        window: int = 800,
        burn_in: int = 300,
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
        verbose: int = 10,
    ) -> None:
        check_choice("features", features, FEATURE_SETS)
        check_choice("target", target, TARGETS)
        check_choice("cell", cell, CELLS)
        check_int("hidden_size", hidden_size, 1, 4096)
        check_int("num_layers", num_layers, 1, 8)
        check_int("window", window, 2)
        check_int("burn_in", burn_in, 0)
        if burn_in >= window:
            raise ValueError(f"burn_in={burn_in!r}: expected fewer samples than window={window}")
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
        check_int("verbose", verbose, 0)
        self.features = features
        self.target = target
        self.cell = cell
        self.hidden_size = hidden_size
        self.num_layers = num_layers
        self.window = window
        self.burn_in = burn_in
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
        self.verbose = verbose

    # -- helpers --------------------------------------------------------------------------------
    def _new_net(self) -> SequenceNet:
        return SequenceNet(len(feature_names(self.features)), self.hidden_size, self.num_layers,
                           self.cell)

    def _inputs(self, x_ref: np.ndarray, ts: float) -> np.ndarray:
        """Normalised features of ``x_ref`` preceded by ``burn_in`` samples at rest."""
        padded = np.concatenate([np.full(self.burn_in, x_ref[0]), x_ref])
        feats = reference_features(padded, ts, self.features, self.v_break_)
        return ((feats - self.feature_mean_) / self.feature_scale_).astype(np.float32)

    def _log(self, msg: str) -> None:
        if self.verbose:
            print(f"[{type(self).__name__}] {msg}", flush=True)

    # -- kernels --------------------------------------------------------------------------------
    def _fit(self, runs: list[Run], ts: float) -> None:
        bv = identify_v_break_multi([r.x_ref for r in runs], [r.x for r in runs], ts)
        self.v_break_ = bv.v_break
        self.tf_ = fit_linear_part(runs, ts, self.n_poles, self.n_zeros, self.dc_gain,
                                   v_break=bv.v_break, pre=self.window_pre,
                                   post=self.window_post)
        raw_x, raw_y = [], []
        for r in runs:
            res = r.x - simulate_tf(self.tf_, r.x_ref, ts)
            if self.target == "friction_error":
                mask = presliding_mask(r.x_ref, ts, bv.v_break, pre=self.window_pre,
                                       post=self.window_post)
                res = np.where(mask, res, 0.0)
            padded = np.concatenate([np.full(self.burn_in, r.x_ref[0]), r.x_ref])
            raw_x.append(reference_features(padded, ts, self.features, bv.v_break))
            raw_y.append(np.concatenate([np.zeros(self.burn_in), res]))
        all_x = np.vstack(raw_x)
        self.feature_mean_ = all_x.mean(axis=0)
        scale = all_x.std(axis=0)
        self.feature_scale_ = np.where(scale > 0, scale, 1.0)
        y_std = float(np.concatenate(raw_y).std())
        self.target_scale_ = y_std if y_std > 0 else 1.0
        wins_x, wins_y = [], []
        for fx, fy in zip(raw_x, raw_y, strict=True):
            if fx.shape[0] < self.window:  # short run: more rest in front
                extra = self.window - fx.shape[0]
                fx = np.vstack([np.repeat(fx[:1], extra, axis=0), fx])
                fy = np.concatenate([np.zeros(extra), fy])
            nx = (fx - self.feature_mean_) / self.feature_scale_
            ny = fy / self.target_scale_
            for s in _window_starts(fx.shape[0], self.window, self.burn_in):
                wins_x.append(nx[s:s + self.window])
                wins_y.append(ny[s:s + self.window])
        x_all = torch.tensor(np.stack(wins_x), dtype=torch.float32)
        y_all = torch.tensor(np.stack(wins_y), dtype=torch.float32)
        every = max(2, int(round(1.0 / self.validation_fraction)))
        is_val = torch.tensor([(i % every) == every // 2 for i in range(len(wins_x))])
        if not bool(is_val.any()) or bool(is_val.all()):
            is_val = torch.zeros(len(wins_x), dtype=torch.bool)
            is_val[-1] = len(wins_x) > 1
        x_tr, y_tr = x_all[~is_val], y_all[~is_val]
        x_va, y_va = (x_all[is_val], y_all[is_val]) if bool(is_val.any()) else (x_tr, y_tr)
        self._log(f"v_break {bv.v_break * 1e3:.3f} mm/s; {sum(len(r.t) for r in runs)} samples,"
                  f" {len(x_tr)} training and {len(x_va)} validation windows of {self.window}")
        b = self.burn_in
        with _torch_determinism(self.seed, self.n_threads):
            net = self._new_net()
            opt = torch.optim.Adam(net.parameters(), lr=self.learning_rate)
            sched = torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=0.5, patience=5)
            gen = torch.Generator().manual_seed(self.seed)
            best_val, best_state, stale = math.inf, None, 0
            history = []
            t0 = time.perf_counter()
            for epoch in range(1, self.max_epochs + 1):
                net.train()
                perm = torch.randperm(len(x_tr), generator=gen)
                total, count = 0.0, 0
                for i in range(0, len(perm), self.batch_size):
                    idx = perm[i:i + self.batch_size]
                    opt.zero_grad()
                    loss = ((net(x_tr[idx]) - y_tr[idx])[:, b:] ** 2).mean()
                    loss.backward()
                    torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
                    opt.step()
                    total += float(loss.detach()) * len(idx)
                    count += len(idx)
                net.eval()
                with torch.no_grad():
                    val = float(((net(x_va) - y_va)[:, b:] ** 2).mean())
                sched.step(val)
                history.append((epoch, total / count, val))
                if val < best_val * (1.0 - 1e-4):
                    best_val, stale = val, 0
                    best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
                else:
                    stale += 1
                if self.verbose and (epoch % self.verbose == 0 or epoch == 1):
                    self._log(f"epoch {epoch:4d}  train {total / count:.4f}  val {val:.4f}  "
                              f"best {best_val:.4f}  {time.perf_counter() - t0:6.1f} s")
                if stale >= self.patience:
                    break
            if best_state is not None:
                net.load_state_dict(best_state)
            net.eval()
        self.train_seconds_ = time.perf_counter() - t0
        self._log(f"done: {len(history)} epochs, best val {best_val:.4f}, "
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
        if n < self.window:
            feats = np.vstack([np.repeat(feats[:1], self.window - n, axis=0), feats])
        starts = _window_starts(feats.shape[0], self.window, self.burn_in)
        with _torch_determinism(self.seed, self.n_threads), torch.no_grad():
            out = self.net_(torch.from_numpy(np.stack([feats[s:s + self.window]
                                                       for s in starts]))).double().numpy()
        y = np.zeros(feats.shape[0])
        for s, o in zip(starts, out, strict=True):
            y[s + self.burn_in:s + self.window] = o[self.burn_in:]
        return y[-x_ref.shape[0]:] * self.target_scale_

    def _predict_position(self, x_ref: np.ndarray) -> np.ndarray:
        return simulate_tf(self.tf_, x_ref, self.ts_) + self.predict_friction_error(x_ref)

    # -- persistence ----------------------------------------------------------------------------
    def _state(self) -> dict[str, torch.Tensor]:
        state = tf_state(self.tf_)
        state["v_break_"] = torch.tensor(self.v_break_, dtype=torch.float64)
        state["feature_mean_"] = torch.tensor(self.feature_mean_, dtype=torch.float64)
        state["feature_scale_"] = torch.tensor(self.feature_scale_, dtype=torch.float64)
        state["target_scale_"] = torch.tensor(self.target_scale_, dtype=torch.float64)
        for k, v in self.net_.state_dict().items():
            state[f"net.{k}"] = v.detach().clone()
        return state

    def _expected_shapes(self, state: dict[str, torch.Tensor]) -> dict[str, tuple[int, ...]]:
        n_feat = len(feature_names(self.features))
        shapes: dict[str, tuple[int, ...]] = {
            "tf_num": (self.n_zeros + 1,), "tf_den": (self.n_poles + 1,), "v_break_": (),
            "feature_mean_": (n_feat,), "feature_scale_": (n_feat,), "target_scale_": ()}
        for k, v in self._new_net().state_dict().items():
            shapes[f"net.{k}"] = tuple(v.shape)
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
