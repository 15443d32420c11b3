"""``tf+stribeck``: physics baseline, a fitted Stribeck friction through the disturbance path.

    x_pred = G(s) x_ref + H_d(z) [ -F_f(v_ref) ]
    F_f(v) = [ f_c + (f_s - f_c) exp(-(v / v_s)^2) ] sgn(v)          (paper, eq. 8)

``G`` is identified from the data as for ``tf+lstm`` (outside the pre-sliding windows).

**This predictor uses knowledge of the true loop.** The disturbance path ``H_d`` (friction force
at the plant to position) is the exact sampled closed loop of the axis from
:func:`fricbench.axis.closed_loop` (its input ``d``), built from the controller gains, the
mass and the damping of ``axis`` (default: the paper-calibrated ``Axis()``). It is not
identified because reference and position alone cannot identify it: a force-to-position
response needs a force excitation or a force measurement, and its gain ``1/M`` and the zero
that the velocity integrator puts at ``s = 0`` are invisible in ``X/X_ref``. A machine builder
knows these parameters (they are the drive's settings and the axis' data sheet), which makes
this the natural physics baseline.

The friction acts at the reference velocity (the feedforward view: the prediction needs the
reference only), so it cannot hold the axis stuck as real static friction does; that is the
limit the data-driven predictors are measured against. ``f_c`` and ``f_s - f_c`` enter
linearly and are fitted by non-negative least squares for each ``v_s`` of a logarithmic grid;
the best ``v_s`` wins.
"""

from __future__ import annotations

import control
import numpy as np
import torch
from scipy import optimize, signal

from fricbench.axis import Axis, closed_loop
from fricbench.predictors.base import Predictor, Run
from fricbench.predictors.tf import check_tf_orders, fit_linear_part, tf_from_state, tf_state
from fricbench.run_events import motion_sign
from fricbench.sysid.friction_error import identify_v_break_multi, reference_velocity
from fricbench.sysid.tf_fit import simulate_tf

__all__ = ["TFStribeckPredictor", "disturbance_path"]

_V_TOL = 1e-6  # m/s


def disturbance_path(axis: Axis) -> tuple[np.ndarray, np.ndarray]:
    """``lfilter`` coefficients of the sampled force-disturbance-to-position response, m/N."""
    sys = closed_loop(axis)
    sub = control.ss(sys.A, sys.B[:, [sys.input_labels.index("d")]], sys.C,
                     sys.D[:, [sys.input_labels.index("d")]], sys.dt)
    tfd = control.ss2tf(sub)
    num = np.asarray(tfd.num[0][0], dtype=float)
    den = np.asarray(tfd.den[0][0], dtype=float)
    num = np.concatenate([np.zeros(len(den) - len(num)), num])
    return num / den[0], den / den[0]


class TFStribeckPredictor(Predictor):
    """TF prediction plus a fitted Stribeck friction through the known disturbance path.

    Parameters
    ----------
    axis : Axis or None, optional
        Whose linear loop gives the disturbance path (``None``: the default ``Axis()``); its
        friction and effects are ignored. Its controller sample time must equal the data's.
    n_poles, n_zeros, dc_gain : optional
        Transfer-function structure (:class:`fricbench.predictors.tf.TFPredictor`).
    vs_grid : int, optional
        Number of Stribeck velocities tried, log-spaced over 0.1..20 mm/s.

    Attributes
    ----------
    tf_ : control.TransferFunction
    fc_, fs_, vs_ : float
        Fitted Coulomb level (N), static level (N), Stribeck velocity (m/s).
    """

    def __init__(self, axis: Axis | None = None, n_poles: int = 3, n_zeros: int = 2,
                 dc_gain: float | None = None, vs_grid: int = 30) -> None:
        if axis is not None and not isinstance(axis, Axis):
            raise TypeError(f"axis={axis!r}: expected an Axis or None")
        check_tf_orders(n_poles, n_zeros, dc_gain)
        if isinstance(vs_grid, bool) or not isinstance(vs_grid, int) or vs_grid < 1:
            raise ValueError(f"vs_grid={vs_grid!r}: expected an integer >= 1")
        self.axis = axis
        self.n_poles = n_poles
        self.n_zeros = n_zeros
        self.dc_gain = dc_gain
        self.vs_grid = vs_grid

    def _path(self, ts: float) -> tuple[np.ndarray, np.ndarray]:
        axis = self.axis if self.axis is not None else Axis()
        if abs(axis.controller.ts - ts) > 1e-6 * ts:
            raise ValueError(f"axis.controller.ts={axis.controller.ts:g} s but the data are "
                             f"sampled at {ts:g} s")
        return disturbance_path(axis)

    @staticmethod
    def _basis(v: np.ndarray, vs: float, b: np.ndarray, a: np.ndarray) -> np.ndarray:
        sgn = motion_sign(v, _V_TOL)
        # friction enters the loop as d = -F_f
        coulomb = signal.lfilter(b, a, -sgn)
        stribeck = signal.lfilter(b, a, -np.exp(-((v / vs) ** 2)) * sgn)
        return np.column_stack([coulomb, stribeck])

    def _fit(self, runs: list[Run], ts: float) -> None:
        b, a = self._path(ts)
        bv = identify_v_break_multi([r.x_ref for r in runs], [r.x for r in runs], ts)
        self.tf_ = fit_linear_part(runs, ts, self.n_poles, self.n_zeros, self.dc_gain,
                                   v_break=bv.v_break)
        vels = [reference_velocity(r.x_ref, ts)[0] for r in runs]
        resid = np.concatenate([r.x - simulate_tf(self.tf_, r.x_ref, ts) for r in runs])
        best = None
        for vs in np.geomspace(1e-4, 2e-2, self.vs_grid):
            mat = np.vstack([self._basis(v, vs, b, a) for v in vels])
            coef, rnorm = optimize.nnls(mat, resid)
            if best is None or rnorm < best[0]:
                best = (rnorm, vs, coef)
        _, vs, (fc, dfs) = best  # type: ignore[misc]  # vs_grid >= 1: best is set
        self.fc_, self.fs_, self.vs_ = float(fc), float(fc + dfs), float(vs)

    def _predict_position(self, x_ref: np.ndarray) -> np.ndarray:
        b, a = self._path(self.ts_)
        v = reference_velocity(x_ref, self.ts_)[0]
        fric = self._basis(v, self.vs_, b, a) @ np.array([self.fc_, self.fs_ - self.fc_])
        return simulate_tf(self.tf_, x_ref, self.ts_) + fric

    def _state(self) -> dict[str, torch.Tensor]:
        state = tf_state(self.tf_)
        state["friction_"] = torch.tensor([self.fc_, self.fs_, self.vs_], dtype=torch.float64)
        return state

    def _expected_shapes(self, state: dict[str, torch.Tensor]) -> dict[str, tuple[int, ...]]:
        return {"tf_num": (self.n_zeros + 1,), "tf_den": (self.n_poles + 1,), "friction_": (3,)}

    def _set_state(self, state: dict[str, torch.Tensor]) -> None:
        self.tf_ = tf_from_state(state)
        self.fc_, self.fs_, self.vs_ = (float(x) for x in state["friction_"])
