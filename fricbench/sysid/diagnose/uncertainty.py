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
of zero is reported as within its uncertainty. That test is the open loop's too, in one place
(:func:`~fricbench.sysid.diagnose.criterion.size_over_sd`): the size's standard deviation is
taken with its shape held and projected off the other kept columns, so it is not the marginal
one reported in ``sd`` (which says how well a value is known, the shape free; the test asks
whether the size can be told from zero, where the shape means nothing).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from fricbench.sysid.diagnose.criterion import (
    described_sd,
    effective_samples,
    held_covariance,
    kept_columns,
    size_over_sd,
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
        Per effect, the marginal standard deviation of each value :func:`describe_parameters`
        reports (same keys, same SI units; every kept parameter free, shapes too).
    size_over_sd : dict
        Per effect, the largest ``|size| / sd`` over its sizes, ``sd`` the conditional one of
        the detection test (:func:`~fricbench.sysid.diagnose.criterion.size_over_sd`), not
        the marginal one in ``sd`` (inf when the data pin a size exactly, never NaN); absent
        for an effect with no size parameter.
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
    # an entry on a bound of its range or one the residual does not move is held at its value,
    # out of the covariance: the rule both loops share (criterion.kept_columns)
    hits = [p.bound_hit(p.from_theta(t)) for p, t in zip(params, theta0, strict=True)]
    keep = kept_columns(jac, np.array([h is not None for h in hits], dtype=bool))
    cov_theta = held_covariance(jac, r0, n_eff, keep)
    # theta -> physical value: d value / d theta is the value (a logarithm) or the scale
    slope = np.array([p.from_theta(t) if p.log else p.scale
                      for p, t in zip(params, theta0, strict=True)])
    cov = cov_theta * np.outer(slope, slope)
    plant_cols = [j for j, p in enumerate(params) if isinstance(p.target, int)]
    idx = [int(params[j].target) for j in plant_cols]
    cov_plant = cov[np.ix_(plant_cols, plant_cols)]
    row = model.plant
    values = np.array([float(row[p.target]) if isinstance(p.target, int) else math.nan
                       for p in params])
    upper = np.array([h == "upper" for h in hits], dtype=bool)
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
        # the detection test both loops share (criterion.size_over_sd): the shape held, each
        # size's sd from its column projected off the other kept ones
        shapes = [col[i] for i in get_effect(name).shape_parameters if i in col]
        out.size_over_sd[name] = size_over_sd(jac, r0, n_eff, keep, [col[i] for i in sizes],
                                              shapes, values=values, slope=slope, upper=upper)
    return out
