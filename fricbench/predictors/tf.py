"""``tf``: the transfer-function-only predictor ``x_pred = G(s) x_ref`` (paper, Sec. 3.1)."""

from __future__ import annotations

from collections.abc import Sequence

import control
import numpy as np
import torch

from fricbench._validation import check_int, check_positive
from fricbench.predictors.base import Predictor, Run
from fricbench.sysid.friction_error import presliding_mask
from fricbench.sysid.tf_fit import fit_tf_multi, simulate_tf

__all__ = ["TFPredictor", "fit_linear_part", "check_tf_orders"]


def check_tf_orders(n_poles: int, n_zeros: int, dc_gain: float | None) -> None:
    """Validate the transfer-function structure arguments shared by the predictors."""
    check_int("n_poles", n_poles, 1, 6)
    check_int("n_zeros", n_zeros, 0, 5)
    if n_zeros >= n_poles:
        raise ValueError(f"n_zeros={n_zeros!r}: expected fewer zeros than poles "
                         f"(n_poles={n_poles})")
    if dc_gain is not None:
        check_positive("dc_gain", dc_gain)


def fit_linear_part(runs: Sequence[Run], ts: float, n_poles: int, n_zeros: int,
                    dc_gain: float | None, v_break: float | None = None, pre: float = 0.02,
                    post: float = 0.1) -> control.TransferFunction:
    """Fit the transfer function on ``runs``; with ``v_break``, outside the pre-sliding windows.

    Leaving the windows out keeps friction transients from bending the linear model (with them
    in, the output-error fit trades accuracy everywhere for a partial fit of the spikes).
    """
    weights = None
    if v_break is not None:
        weights = [(~presliding_mask(r.x_ref, ts, v_break, pre=pre, post=post)).astype(float)
                   for r in runs]
    return fit_tf_multi([r.x_ref for r in runs], [r.x for r in runs], ts, n_poles, n_zeros,
                        dc_gain=dc_gain, weights=weights)


def tf_state(tf: control.TransferFunction) -> dict[str, torch.Tensor]:
    """Numerator and denominator of ``tf`` as float64 tensors."""
    return {"tf_num": torch.tensor(np.asarray(tf.num[0][0], dtype=float)),
            "tf_den": torch.tensor(np.asarray(tf.den[0][0], dtype=float))}


def tf_from_state(state: dict[str, torch.Tensor]) -> control.TransferFunction:
    """Inverse of :func:`tf_state`."""
    num = state["tf_num"].double().numpy()
    den = state["tf_den"].double().numpy()
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))) or den[0] == 0:
        raise ValueError("transfer-function coefficients are not finite")
    return control.tf(num.tolist(), den.tolist())


class TFPredictor(Predictor):
    """Transfer function only: ``x_pred = G(s) x_ref`` (free-run simulation).

    Parameters
    ----------
    n_poles, n_zeros : int, optional
        Structure of ``G``. Default ``(3, 2)``: the default axis has a PI velocity loop, whose
        reference-to-position response is third order (the paper's eq. 22 is ``(2, 1)``, a loop
        without integral action; ``(2, 1)`` on our axis leaves the whole 3 um linear error of
        M-serial unexplained).
    dc_gain : float or None, optional
        ``None``: DC gain fitted; a number: constrained (see :func:`fricbench.sysid.fit_tf`).

    Attributes
    ----------
    tf_ : control.TransferFunction
        Identified ``G(s)``, fitted on every sample of the runs (output error).
    ts_ : float
        Sample time, s.
    """

    needs_reversals = False

    def __init__(self, n_poles: int = 3, n_zeros: int = 2, dc_gain: float | None = None) -> None:
        check_tf_orders(n_poles, n_zeros, dc_gain)
        self.n_poles = n_poles
        self.n_zeros = n_zeros
        self.dc_gain = dc_gain

    def _fit(self, runs: list[Run], ts: float) -> None:
        self.tf_ = fit_linear_part(runs, ts, self.n_poles, self.n_zeros, self.dc_gain)

    def _predict_position(self, x_ref: np.ndarray) -> np.ndarray:
        return simulate_tf(self.tf_, x_ref, self.ts_)

    def _state(self) -> dict[str, torch.Tensor]:
        return tf_state(self.tf_)

    def _expected_shapes(self, state: dict[str, torch.Tensor]) -> dict[str, tuple[int, ...]]:
        return {"tf_num": (self.n_zeros + 1,), "tf_den": (self.n_poles + 1,)}

    def _set_state(self, state: dict[str, torch.Tensor]) -> None:
        self.tf_ = tf_from_state(state)
