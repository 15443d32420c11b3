"""The servo feed axis: its parameter sets (:mod:`fricbench.axis.sections`) and a friction law.

All values are SI (m, s, kg, N, A). The defaults are the paper-calibrated axis; where each
number comes from is in ``docs/default_axis.md``. An :class:`Axis` checks on construction that
its sampled linear loop (:func:`fricbench.axis.linear.check_stability`) is stable.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from fricbench.axis import kernel as K
from fricbench.axis import plant as PL
from fricbench.axis.linear import check_stability
from fricbench.axis.sections import ControllerParams, Effects, MechanicsParams
from fricbench.friction import FrictionModel, Stribeck, make_friction

__all__ = ["Axis", "ControllerParams", "Effects", "MechanicsParams"]


def _coerce(cls: type, value: Any, name: str) -> Any:
    if isinstance(value, cls):
        return value
    if isinstance(value, dict):
        try:
            return cls(**value)
        except TypeError as exc:
            raise TypeError(f"{name}: {exc}") from None
    raise TypeError(f"{name}={value!r}: expected {cls.__name__} or a dict of its fields")


@dataclass(frozen=True)
class Axis:
    """One servo feed axis: controller, mechanics, friction and effects.

    Parameters
    ----------
    controller : ControllerParams
    mechanics : MechanicsParams
    friction : FrictionModel
        Any registered friction model (default: the paper-calibrated Stribeck law).
    effects : Effects

    Raises
    ------
    ValueError
        If the sampled linear loop (controller, mechanics, substeps and actuator delay; friction
        left out) is unstable (:func:`fricbench.axis.linear.check_stability`). Change gains and
        mechanics together (``Axis.from_dict`` or ``dataclasses.replace``) when a step in
        between would be unstable.

    Examples
    --------
    >>> from fricbench.axis import Axis
    >>> axis = Axis()                      # the paper-calibrated default axis
    >>> axis.with_friction("lugre").friction.id
    'lugre'
    """

    controller: ControllerParams = field(default_factory=ControllerParams)
    mechanics: MechanicsParams = field(default_factory=MechanicsParams)
    friction: FrictionModel = field(default_factory=Stribeck)
    effects: Effects = field(default_factory=Effects)

    def __post_init__(self) -> None:
        if not isinstance(self.controller, ControllerParams):
            raise TypeError(f"controller={self.controller!r}: expected ControllerParams")
        if not isinstance(self.mechanics, MechanicsParams):
            raise TypeError(f"mechanics={self.mechanics!r}: expected MechanicsParams")
        if not isinstance(self.friction, FrictionModel):
            raise TypeError(f"friction={self.friction!r}: expected a FrictionModel")
        if not isinstance(self.effects, Effects):
            raise TypeError(f"effects={self.effects!r}: expected Effects")
        # an unstable loop would run bounded by the current saturation, silently: refuse it
        check_stability(self)

    # -- construction helpers -----------------------------------------------------------------
    @classmethod
    def from_dict(cls, spec: dict[str, Any]) -> Axis:
        """Build from ``{"controller": {...}, "mechanics": {...}, "friction": {"id": ...},
        "effects": {...}}`` (every section optional), as in the env TOML specs."""
        unknown = set(spec) - {"controller", "mechanics", "friction", "effects"}
        if unknown:
            raise ValueError(f"axis spec: unknown sections {sorted(unknown)}; expected "
                             "controller, mechanics, friction, effects")
        fr = spec.get("friction", {"id": "stribeck"})
        if isinstance(fr, FrictionModel):
            friction = fr
        else:
            fr = dict(fr)
            friction = make_friction(fr.pop("id", "stribeck"), **fr)
        return cls(
            controller=_coerce(ControllerParams, spec.get("controller", {}), "controller"),
            mechanics=_coerce(MechanicsParams, spec.get("mechanics", {}), "mechanics"),
            friction=friction,
            effects=_coerce(Effects, spec.get("effects", {}), "effects"),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON/TOML-ready form accepted by :meth:`from_dict`."""
        return {"controller": asdict(self.controller), "mechanics": asdict(self.mechanics),
                "friction": self.friction.to_dict(), "effects": asdict(self.effects)}

    def with_friction(self, friction: FrictionModel | str, **params: Any) -> Axis:
        """A copy with another friction model (instance, or registered id plus parameters)."""
        fr = friction if isinstance(friction, FrictionModel) else make_friction(friction, **params)
        return replace(self, friction=fr)

    def with_effects(self, **changes: Any) -> Axis:
        """A copy with some effect parameters changed."""
        return replace(self, effects=replace(self.effects, **changes))

    def with_controller(self, **changes: Any) -> Axis:
        """A copy with some controller parameters changed."""
        return replace(self, controller=replace(self.controller, **changes))

    def with_mechanics(self, **changes: Any) -> Axis:
        """A copy with some mechanics parameters changed."""
        return replace(self, mechanics=replace(self.mechanics, **changes))

    def without_friction(self) -> Axis:
        """A copy with zero friction (the linear axis, for oracles and TF fits)."""
        return replace(self, friction=make_friction("viscous", fv=0.0))

    # -- kernel packing ---------------------------------------------------------------------
    def pack(self) -> np.ndarray:
        """Parameter row of length ``kernel.N_PARAMS`` for the batched kernel."""
        c, m, e = self.controller, self.mechanics, self.effects
        f = self.friction.kernel_params()
        p = np.zeros(K.N_PARAMS)
        p[K.P_TS] = c.ts
        p[K.P_NSUB] = c.n_substeps
        p[K.P_M] = m.mass
        p[K.P_B] = m.damping
        p[K.P_KT] = c.kt
        p[K.P_IMAX] = c.i_max
        p[K.P_KP] = c.kp
        p[K.P_KVFF] = c.kvff
        p[K.P_KAFF] = c.kaff
        p[K.P_KV] = c.kv
        # the kernel integrates I in velocity units: I += Ts/Ti e_v
        p[K.P_TI] = c.ti
        if c.law == "linear":
            p[K.P_LAW] = 1.0
            p[K.P_LAW_NA] = len(c.law_recursion)
            p[K.P_LAW_NC] = len(c.law_position)
            p[K.P_LAW_NR] = len(c.law_reference_history)
            p[K.P_LAW_KX], p[K.P_LAW_KV], p[K.P_LAW_KA] = c.law_reference
            p[K.P_LAW_A:K.P_LAW_A + len(c.law_recursion)] = c.law_recursion
            p[K.P_LAW_C:K.P_LAW_C + len(c.law_position)] = c.law_position
            p[K.P_LAW_G:K.P_LAW_G + len(c.law_reference_history)] = c.law_reference_history
        p[K.P_FLOAD] = m.load
        p[K.P_FKIND] = f["kind"]
        p[K.P_FC] = f["fc"]
        # the plant holds the static level as its excess over the Coulomb level
        p[K.P_FS_EXCESS] = f["fs"] - f["fc"]
        p[K.P_VS] = f["vs"]
        p[K.P_DELTA] = f["delta"]
        p[K.P_FV] = f["fv"]
        p[K.P_SIGMA0] = f["sigma0"]
        p[K.P_SIGMA1] = f["sigma1"]
        p[K.P_BACKLASH] = e.backlash
        p[K.P_MEAS_TABLE] = 1.0 if e.measurement == "table" else 0.0
        # A sin(2 pi x / lambda + phi) = A cos(phi) sin(2 pi x / lambda) + A sin(phi) cos(...)
        p[K.P_COG_SIN] = e.cogging_amplitude * math.cos(e.cogging_phase)
        p[K.P_COG_COS] = e.cogging_amplitude * math.sin(e.cogging_phase)
        p[K.P_COG_PERIOD] = e.cogging_period
        phases = e.cogging_harmonic_phases or (0.0,) * len(e.cogging_harmonics)
        for col, amp, ph in zip((PL.COG_H2_SIN, PL.COG_H3_SIN), e.cogging_harmonics, phases,
                                strict=False):
            p[col] = amp * math.cos(ph)
            p[col + 1] = amp * math.sin(ph)
        p[K.P_PD_GRAD] = e.friction_gradient
        p[PL.PD_CENTER] = e.friction_gradient_center
        p[K.P_DFC] = e.coulomb_asymmetry
        p[K.P_DB] = e.viscous_asymmetry
        p[K.P_PD_SIN] = e.friction_variation * math.cos(e.friction_variation_phase)
        p[K.P_PD_COS] = e.friction_variation * math.sin(e.friction_variation_phase)
        p[K.P_PD_PERIOD] = e.friction_variation_period
        n_knots = len(e.friction_profile)
        p[PL.PD_NKNOTS] = n_knots
        p[PL.PD_START] = e.friction_profile_start
        p[PL.PD_SPAN] = e.friction_profile_span
        p[PL.PD_KNOT0:PL.PD_KNOT0 + n_knots] = e.friction_profile
        p[K.P_TH_AMP] = e.thermal_drift
        p[K.P_TH_TAU] = e.thermal_time_constant
        p[PL.TH_VHEAT] = e.thermal_heating_speed
        p[PL.TH_STRAIN] = e.thermal_strain
        p[PL.TH_X0] = e.thermal_strain_origin
        p[K.P_QUANT] = e.quantization
        p[K.P_NOISE] = e.noise_std
        p[K.P_DELAY] = e.delay_samples
        p[K.P_COMP_RATIO] = e.compliance_load_fraction
        p[K.P_COMP_FREQ] = e.compliance_frequency
        p[K.P_COMP_ZETA] = e.compliance_damping
        p[PL.BL_LOAD] = e.backlash_load_fraction
        p[PL.COMP_LOAD] = 1.0 if e.compliance_friction == "load" else 0.0
        p[PL.COMP_B_MOTOR] = e.compliance_damping_motor_share
        return p

    @property
    def needs_noise(self) -> bool:
        """Whether simulations draw random numbers (measurement noise on)."""
        return self.effects.noise_std > 0.0
