"""Where a validation run leaves the range the training run covered.

A model fitted on one run is only known inside the motion that run showed it: its forces at
the speeds the run reached, its position effects (cogging, a friction level varying along the
stroke) over the stroke it travelled. A validation run that goes further tests how the model
extrapolates as much as the effects found, and a user reading its error must know that. The
shared DC motor's sine run moves at 57 deg/s at most but for its start-up (92 deg/s, its
99th percentile); its step run goes faster on 9 % of its samples (up to 119 deg/s), where the
effort rises with the speed about twice as steeply as at the sine's speeds: no model fitted
to the sine run can know that, and its error on the step run says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fricbench.sysid.diagnose.prepared import Prepared
from fricbench.sysid.diagnose.settings import defaults

__all__ = ["Coverage", "coverage"]


@dataclass(frozen=True)
class Coverage:
    """How much of a validation run lies beyond the training run's reach.

    Attributes
    ----------
    speed_reach : float
        The training run's speed reach (``settings.reach_quantile`` of its filtered speed), SI.
    speed_max_validation : float
        The validation run's largest filtered speed, SI.
    share_faster : float
        Share of the validation samples faster than the reach by ``settings.reach_margin``.
    stroke : tuple of float
        The training run's covered positions (its ``settings.reach_quantile`` range), SI.
    share_outside : float
        Share of the validation samples outside that range by more than
        ``settings.reach_margin`` of its width.
    """

    speed_reach: float
    speed_max_validation: float
    share_faster: float
    stroke: tuple[float, float]
    share_outside: float

    def to_dict(self) -> dict[str, float]:
        """JSON-ready figures (SI: m or m/s, keyed in rad on a rotary axis)."""
        return {"speed_reach_training_m_s": self.speed_reach,
                "speed_max_validation_m_s": self.speed_max_validation,
                "share_faster_pct": 100.0 * self.share_faster,
                "stroke_training_low_m": self.stroke[0],
                "stroke_training_high_m": self.stroke[1],
                "share_outside_stroke_pct": 100.0 * self.share_outside,
                "reach_quantile": defaults().reach_quantile,
                "reach_margin": defaults().reach_margin}

    def warnings(self, prep: Prepared) -> list[str]:
        """What a user must know before reading the validation error (units of the log)."""
        unit = prep.run.logged_unit
        out = []
        if self.share_faster > defaults().beyond_share:
            k, u = unit.velocity_per_si, unit.velocity_display
            out.append(f"the validation run moves faster than the training run did on "
                       f"{100 * self.share_faster:.0f} % of its samples (up to "
                       f"{k * self.speed_max_validation:.4g} {u}; the training run's "
                       f"{100 * defaults().reach_quantile:.0f}th percentile is "
                       f"{k * self.speed_reach:.4g} "
                       f"{u}): there the model's forces are extrapolated, and the validation "
                       "error tells as much about that as about the effects found")
        if self.share_outside > defaults().beyond_share:
            k, u = unit.coarse_per_si, unit.coarse_display
            out.append(f"the validation run leaves the stroke the training run covered "
                       f"({k * self.stroke[0]:.4g} to {k * self.stroke[1]:.4g} {u}) on "
                       f"{100 * self.share_outside:.0f} % of its samples: position effects "
                       "(cogging, a friction level varying along the stroke) are extrapolated "
                       "there")
        return out


def coverage(train: Prepared, validation: Prepared) -> Coverage:
    """How much of ``validation`` lies beyond what ``train`` covered (filtered speed and
    measured position; both runs prepared with the same derivative filter).

    Parameters
    ----------
    train, validation : Prepared

    Returns
    -------
    Coverage
    """
    speed_t = np.abs(train.vf)
    speed_v = np.abs(validation.vf)
    reach = float(np.quantile(speed_t, defaults().reach_quantile))
    cfg = defaults()
    faster = float(np.mean(speed_v > (1.0 + cfg.reach_margin) * reach)) if reach > 0.0 else 0.0
    lo, hi = (float(q) for q in np.quantile(train.x, [1.0 - cfg.reach_quantile,
                                                      cfg.reach_quantile]))
    margin = cfg.reach_margin * (hi - lo)
    outside = float(np.mean((validation.x < lo - margin) | (validation.x > hi + margin)))
    return Coverage(speed_reach=reach, speed_max_validation=float(np.max(speed_v)),
                    share_faster=faster, stroke=(lo, hi), share_outside=outside)
