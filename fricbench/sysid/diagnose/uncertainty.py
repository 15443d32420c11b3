"""Standard deviations of the closed-loop model's parameters, and which effects they detect.

The open loop's final fit carries its Jacobian (:mod:`fricbench.sysid.diagnose.open_loop`);
the closed loop's final model is the search's last refit, so its Jacobian is taken here, once,
at that model: one batch of free runs, every free parameter of the model moved by a finite
step (the loop gains of a cascade fitted to the position, the damping, every effect's
parameters). The covariance is the output-error one of the diagnosis' criterion module,
``tau s^2 (J^T J)^-1`` (:func:`~fricbench.sysid.diagnose.criterion.parameter_covariance`),
carried to the reported values by the delta method. With every free parameter in the
Jacobian, each standard deviation is the marginal one: a size the loop gains could take up
is reported as uncertain, not as fitted.

An effect whose every size (its parameters that are not a shape: a gap, a level, an
amplitude; not a period or a time constant) lies within
:attr:`~fricbench.sysid.diagnose.settings.DiagnoseSettings.detection_sd` standard deviations
of zero is reported as within its uncertainty.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from fricbench.sysid.diagnose.criterion import (
    UNIDENTIFIED,
    described_sd,
    effective_samples,
    parameter_covariance,
)
from fricbench.sysid.diagnose.effects import describe_parameters, get_effect, size_entries
from fricbench.sysid.diagnose.leastsq import batched_jacobian
from fricbench.sysid.diagnose.models import (
    Bounds,
    GreyBox,
    PositionFit,
    _lm_box,
    _models_at,
    position_params,
)
from fricbench.sysid.diagnose.prepared import Prepared
from fricbench.sysid.diagnose.settings import DEFAULT_SETTINGS, DiagnoseSettings

__all__ = ["ModelUncertainty", "model_uncertainty"]


@dataclass
class ModelUncertainty:
    """Uncertainty of a closed-loop model's parameters.

    Attributes
    ----------
    sd : dict
        Per effect, the standard deviation of each value :func:`describe_parameters` reports
        (same keys, same SI units).
    size_over_sd : dict
        Per effect, the largest ``|size| / sd`` over its sizes (inf when the data pin a size
        exactly, never NaN); absent for an effect with no size parameter.
    n_eff : float
        Independent samples the residual is worth (the covariance's ``n / tau``).
    n_params : int
        Free parameters in the Jacobian.
    """

    sd: dict[str, dict[str, float]] = field(default_factory=dict)
    size_over_sd: dict[str, float] = field(default_factory=dict)
    n_eff: float = 0.0
    n_params: int = 0

    def within(self, detection_sd: float) -> list[str]:
        """Effects whose every size lies within ``detection_sd`` standard deviations of 0."""
        return [e for e, z in self.size_over_sd.items() if z <= detection_sd]

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form (finite numbers only: an infinite ratio is left out)."""
        return {"parameter_sd": self.sd,
                "size_over_sd": {e: z for e, z in self.size_over_sd.items()
                                 if math.isfinite(z)},
                "n_eff": self.n_eff, "n_params": self.n_params}


def model_uncertainty(model: GreyBox, prep: Prepared, b: Bounds, w: np.ndarray | None = None,
                      *, force_unit: str = "N",
                      settings: DiagnoseSettings = DEFAULT_SETTINGS) -> ModelUncertainty:
    """Standard deviations of ``model``'s reported values from the Jacobian at ``model``.

    Parameters
    ----------
    model : GreyBox
        The final model (its values are taken as the optimum).
    prep : Prepared
    b : Bounds
    w : ndarray, optional
        Injected effort of the run.
    force_unit : str
        Unit of the force parameters, as reported.
    settings : DiagnoseSettings

    Returns
    -------
    ModelUncertainty
        Empty (no effect) when the model has no effect or its free run is not finite.
    """
    if not model.effects:
        return ModelUncertainty()
    params = position_params(model, b, controller=True, effects=list(model.effects))
    fit = PositionFit(prep, params, None, w)
    theta0, _, hi, steps = _lm_box(params, model)
    finite: list[bool] = []

    def residuals(thetas: np.ndarray) -> np.ndarray:
        ys, loads = fit._simulate(_models_at(model, params, thetas))
        if thetas.shape[0] == 1:
            finite.append(bool(np.all(np.isfinite(ys[0]))))
        return np.array([fit._resid(y, None if loads is None else loads[i])
                         for i, y in enumerate(ys)])

    # the fit's own finite differences (a step that would leave the box goes the other way)
    fun, jacobian = batched_jacobian(residuals, steps, hi)
    r0 = fun(theta0)
    if not finite[-1]:
        return ModelUncertainty()
    jac = jacobian(theta0)
    n_eff = effective_samples(r0, settings.max_lag_share)
    # an entry on a bound of its range (an active constraint: no free parameter there) or one
    # the residual does not move is held at its value, as in the open loop: its variance is
    # UNIDENTIFIED and the others' covariance is taken without it, so that rounding along its
    # direction leaks into none of them
    norms = np.sqrt(np.sum(jac ** 2, axis=0))
    moved = norms > 1e-10 * max(float(np.max(norms, initial=0.0)), 1e-300)
    hits = [p.bound_hit(p.from_theta(t)) for p, t in zip(params, theta0, strict=True)]
    keep = moved & np.array([h is None for h in hits], dtype=bool)
    cov_theta = _held_covariance(jac, r0, n_eff, keep)
    # theta -> physical value: d value / d theta is the value (a logarithm) or the scale
    slope = np.array([p.from_theta(t) if p.log else p.scale
                      for p, t in zip(params, theta0, strict=True)])
    cov = cov_theta * np.outer(slope, slope)
    plant_cols = [j for j, p in enumerate(params) if isinstance(p.target, int)]
    idx = [int(params[j].target) for j in plant_cols]
    cov_plant = cov[np.ix_(plant_cols, plant_cols)]
    row = model.plant
    fd = np.array([1e-6 * max(abs(float(row[i])), 1e-9) for i in idx])
    out = ModelUncertainty(n_eff=n_eff, n_params=len(params))
    col = {int(params[j].target): j for j in plant_cols}
    for name in model.effects:
        out.sd[name] = described_sd(functools.partial(describe_parameters, name,
                                                      force_unit=force_unit),
                                    row, idx, cov_plant, fd)
        sizes = size_entries(name, idx)
        if not sizes:
            continue
        # a shape (a period, a time constant, a Stribeck velocity) means nothing when the size
        # is zero, so the test of the size holds the shape at its fitted value (Davies 1977):
        # a drift still short of its asymptote determines its slope, not its level and time
        # constant apart, and it is there all the same
        shapes = [col[i] for i in get_effect(name).shape_parameters if i in col]
        keep_e = keep.copy()
        keep_e[shapes] = False
        zs = []
        for i in sizes:
            j = col[i]
            if hits[j] == "upper":
                zs.append(math.inf)
            elif not keep_e[j]:
                zs.append(0.0)  # on its lower bound, or moving nothing: no size seen
            else:
                sd = _conditional_sd(jac, r0, n_eff, j, keep_e) * abs(float(slope[j]))
                zs.append(abs(float(row[i])) / sd if sd > 0.0 else math.inf)
        out.size_over_sd[name] = max(zs)
    return out


def _conditional_sd(jac: np.ndarray, r0: np.ndarray, n_eff: float, j: int, keep: np.ndarray
                    ) -> float:
    """Standard deviation of column ``j``'s parameter, the other kept columns free.

    ``sqrt(tau s^2) / |P J_j|``, ``P`` the projection off the span of the other kept
    columns: the diagonal of ``tau s^2 (J^T J)^-1`` where that is invertible, and still right
    where the other columns are collinear among themselves (two loop gains the run cannot tell
    apart say nothing of a cogging's amplitude), which the inverse's regularised directions
    would leak into every parameter. Infinite when column ``j`` lies in their span.
    """
    n = jac.shape[0]
    others = np.flatnonzero(keep)
    others = others[others != j]
    target = jac[:, j]
    if others.size:
        a = jac[:, others]
        norms = np.sqrt(np.sum(a ** 2, axis=0))
        a = a / np.where(norms > 0.0, norms, 1.0)
        coef = np.linalg.lstsq(a, target, rcond=1e-10)[0]
        target = target - a @ coef
    along = float(np.linalg.norm(target))
    dof = max(n - int(others.size) - 1, 1)
    s2 = float(np.dot(r0, r0)) / dof
    tau = n / max(n_eff, 1.0)
    if along <= 1e-12 * max(float(np.linalg.norm(jac[:, j])), 1e-300):
        return math.inf
    return math.sqrt(tau * s2) / along


def _held_covariance(jac: np.ndarray, r0: np.ndarray, n_eff: float, keep: np.ndarray
                     ) -> np.ndarray:
    """Covariance of every column of ``jac``, those not in ``keep`` held at their values
    (variance :data:`UNIDENTIFIED`, no covariance with the others)."""
    p = jac.shape[1]
    cov = np.zeros((p, p))
    cov[np.diag_indices(p)] = UNIDENTIFIED
    kept = np.flatnonzero(keep)
    if kept.size:
        cov[np.ix_(kept, kept)] = parameter_covariance(jac[:, kept], r0, n_eff)
    return cov
