"""Parameter sets of the servo feed axis: cascade controller, mechanics and optional effects.

All values are SI (m, s, kg, N, A). The defaults are the paper-calibrated axis; where each
number comes from is in ``docs/default_axis.md``. :class:`~fricbench.axis.Axis` joins them with
a friction law; the linear loop of :mod:`fricbench.axis.linear` is built from them alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fricbench._validation import (
    check_choice,
    check_finite,
    check_int,
    check_nonneg,
    check_positive,
    check_range,
)
from fricbench.axis import kernel as K
from fricbench.axis import plant as PL

__all__ = ["ControllerParams", "Effects", "MechanicsParams"]


def _numbers(name: str, value: object, most: int) -> tuple[float, ...]:
    """``value`` as a tuple of at most ``most`` numbers (a TOML array arrives as a list)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        raise ValueError(f"{name}={value!r}: expected a sequence of numbers")
    if len(value) > most:
        raise ValueError(f"{name}: {len(value)} entries, expected at most {most}")
    return tuple(check_finite(f"{name}[{i}]", v) for i, v in enumerate(value))


@dataclass(frozen=True)
class ControllerParams:
    """Cascade controller: position P with feedforward, velocity PI, current gain.

    Parameters
    ----------
    ts : float
        Control sample time, s (position and velocity loop, zero-order hold).
    n_substeps : int
        Fixed plant substeps per sample (integration step ``ts / n_substeps``).
    kp : float
        Position gain, 1/s.
    kvff : float
        Velocity feedforward fraction (1 = full).
    kaff : float
        Acceleration (inertia) feedforward fraction (1 = full ``M a_r``).
    kv : float
        Velocity PI proportional gain, A s/m (current per velocity error).
    ti : float
        Velocity PI integral time, s (0 disables the integral).
    kt : float
        Force constant of motor and screw on the table side, N/A.
    i_max : float
        Current saturation, A.
    law : {"cascade", "linear"}
        The controller: the cascade above, or an identified linear discrete law (the digital
        twin of a measured axis, written by ``fricbench diagnose --env-out``) that replaces
        ``kp, kvff, kaff, kv, ti``:
        ``i[k] = sum_i a_i i[k-i] + k_x x_r[k] + k_v v_r[k] + k_a a_r[k]
        + sum_m g_m x_r[k-m] + sum_j c_j x[k-j]``.
    law_reference : tuple of float
        ``(k_x, k_v, k_a)``: the law's gains on the reference position (A/m), velocity
        (A s/m) and acceleration (A s^2/m).
    law_position : tuple of float
        ``c_0 .. c_(nc-1)``: its gains on the measured position ``x[k] .. x[k-nc+1]``, A/m
        (at most :data:`~fricbench.axis.kernel.LAW_NC_MAX`).
    law_recursion : tuple of float
        ``a_1 .. a_na``: its gains on its own past outputs (``a_1 = 1``: an integrator; at most
        :data:`~fricbench.axis.kernel.LAW_NA_MAX`).
    law_reference_history : tuple of float
        ``g_1 .. g_nr``: its gains on the past reference ``x_r[k-1] .. x_r[k-nr]``, A/m (at most
        :data:`~fricbench.axis.kernel.LAW_NR_MAX`).
    """

    ts: float = 1.0e-3
    n_substeps: int = 5
    kp: float = 180.0
    kvff: float = 1.0
    kaff: float = 0.0
    kv: float = 300.0
    ti: float = 0.02
    kt: float = 600.0
    i_max: float = 15.0
    law: str = "cascade"
    law_reference: tuple[float, ...] = ()
    law_position: tuple[float, ...] = ()
    law_recursion: tuple[float, ...] = ()
    law_reference_history: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        check_range("ts", self.ts, 1e-5, 0.1, "s")
        check_int("n_substeps", self.n_substeps, 1, 1000)
        check_nonneg("kp", self.kp, "1/s")
        check_range("kvff", self.kvff, 0.0, 2.0)
        check_range("kaff", self.kaff, 0.0, 2.0)
        check_nonneg("kv", self.kv, "A s/m")
        check_nonneg("ti", self.ti, "s")
        check_positive("kt", self.kt, "N/A")
        check_positive("i_max", self.i_max, "A")
        check_choice("law", self.law, ("cascade", "linear"))
        sizes = {"law_reference": (3, 3), "law_position": (1, K.LAW_NC_MAX),
                 "law_recursion": (0, K.LAW_NA_MAX),
                 "law_reference_history": (0, K.LAW_NR_MAX)}
        for name, (lo, hi) in sizes.items():
            value = getattr(self, name)
            if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
                raise TypeError(f"{name}={value!r}: expected a sequence of numbers")
            coef = tuple(check_finite(f"{name}[{i}]", v) for i, v in enumerate(value))
            object.__setattr__(self, name, coef)
            if self.law == "linear" and not lo <= len(coef) <= hi:
                raise ValueError(f"{name}={list(coef)!r}: expected {lo} to {hi} numbers for "
                                 "law='linear'")
            if self.law == "cascade" and coef:
                raise ValueError(f"{name}={list(coef)!r}: a coefficient of the linear law, "
                                 "given with law='cascade'; set law='linear' or leave it out")


@dataclass(frozen=True)
class MechanicsParams:
    """Rigid mechanics reduced to the table: ``M dv/dt = F - B v - F_f - F_load``.

    Parameters
    ----------
    mass : float
        Reflected mass of rotor, screw and table, kg.
    damping : float
        Linear viscous damping ``B``, N s/m.
    load : float
        Constant load force opposing positive motion (gravity on a vertical axis, cutting), N.
    """

    mass: float = 400.0
    damping: float = 200.0
    load: float = 0.0

    def __post_init__(self) -> None:
        check_positive("mass", self.mass, "kg")
        check_nonneg("damping", self.damping, "N s/m")
        check_finite("load", self.load)


@dataclass(frozen=True)
class Effects:
    """Optional real effects, each off by default and one parameter away.

    Parameters
    ----------
    backlash : float
        Lost motion between motor and table, m: a play operator (the table stops the instant
        the motor leaves it), or two bodies across the gap with ``backlash_load_fraction``.
    measurement : {"motor", "table"}
        Feedback sensor: rotary encoder on the motor (semi-closed loop) or linear scale on the
        table (full closed loop). Logged positions are always the table's.
    cogging_amplitude : float
        Amplitude of the force ripple ``A sin(2 pi x / period + phase)``, N.
    cogging_period : float
        Spatial period of the ripple, m (e.g. screw lead / pole pairs).
    cogging_phase : float
        Phase of the ripple, rad.
    cogging_harmonics : tuple of float
        Amplitudes of the ripple's second and third harmonics, N (``A_h sin(2 pi h x / period
        + phase_h)``, ``h = 2, 3``): a linear motor's magnets, a motor's slots against its
        poles. Empty (the default), or one or two entries.
    cogging_harmonic_phases : tuple of float
        Their phases, rad: empty (all 0) or one per harmonic.
    friction_gradient : float
        Linear change of the friction levels along the stroke, 1/m
        (``1 + grad (x - friction_gradient_center)``).
    friction_gradient_center : float
        Position where the gradient's factor is 1, m.
    coulomb_asymmetry : float
        Coulomb level moving forward minus moving backward, N (``fc +- asymmetry / 2``).
    viscous_asymmetry : float
        Viscous damping moving forward minus moving backward, N s/m (``B +- asymmetry / 2``).
    friction_variation : float
        Relative amplitude of a periodic friction variation along the stroke (0..0.9).
    friction_variation_period : float
        Its spatial period, m.
    friction_variation_phase : float
        Its phase, rad.
    friction_profile : tuple of float
        A friction level of any shape along the stroke: the relative changes of the friction
        levels (each -0.9 .. 2) at equally spaced knots from ``friction_profile_start`` over
        ``friction_profile_span``, linear between knots and held beyond the end knots (a worn
        or dirty stretch of the guides: ``(0, 0, 0.4, 0, 0)``). Empty (the default): off. At
        most 12 knots (:data:`fricbench.axis.plant.PD_MAX_KNOTS`).
    friction_profile_start : float
        Position of the profile's first knot, m.
    friction_profile_span : float
        From the first knot to the last, m (> 0 with two knots or more).
    thermal_drift : float
        Thermal growth of the table position relative to the motor, m: the final growth
        ``d_inf`` of ``d(t) = d_inf (1 - exp(-t/tau))``, or with a heating speed the growth in
        sustained motion at that speed (seen when measuring on the motor side).
    thermal_time_constant : float
        Its time constant ``tau``, s.
    thermal_heating_speed : float
        Motor speed ``v_heat`` that heats the axis to its growth ``thermal_drift``, m/s; 0 (the
        default) makes the drift a function of time. Above 0 the drift is driven by motion: a
        normalised temperature follows ``tau dtheta/dt = |v_motor| / v_heat - theta`` from 0
        at the start of a run, the drift is ``thermal_drift * theta`` and relaxes at rest.
    thermal_strain : float
        Part of the growth proportional to the table position (a screw grows from its fixed
        bearing), per metre from ``thermal_strain_origin``: the growth at ``x`` is
        ``thermal_drift + thermal_strain (x - thermal_strain_origin)`` (0, the default: the
        same growth all along the stroke). Dimensionless, at most 1e-3 in size (steel warmed
        by 20 K strains 2.3e-4).
    thermal_strain_origin : float
        Position the strain's part is measured from, m.
    quantization : float
        Encoder step, m (rad on a rotary axis; 0: ideal), at most 0.1 (a hobby rig's
        potentiometer on a 10-bit ADC reads 0.061 rad a count).
    noise_std : float
        Standard deviation of additive measurement noise, m.
    delay_samples : int
        Pure delay of the current command, samples (0..16).
    current_noise_std : float
        Standard deviation of the current-measurement noise, A: added to the motor current the
        drive reports (the observation's motor force, ``SimulationResult.u``), not to the
        current that drives the axis (the current loop is taken as ideal at these bandwidths).
    compliance_load_fraction : float
        Compliant axis: the share ``r = m_L / M`` of the mass that is the load (table) behind
        a spring and a damper (coupling, screw, nut); 0 (the default) is the rigid axis. The
        motor side ``(1 - r) M`` takes the motor force, the friction, the damping, the load
        force and the cogging; ``measurement = "table"`` feeds back the load side, and logged
        positions are the load's (:mod:`fricbench.axis.plant`). At most 0.95.
    compliance_frequency : float
        Resonance of the free two-mass axis ``f_r = sqrt(k / mu) / (2 pi)``, Hz
        (``mu = m_M m_L / M``; the motor side's anti-resonance is ``f_r sqrt(1 - r)``).
    compliance_damping : float
        Damping ratio ``zeta`` of that resonance (``c = 2 zeta mu 2 pi f_r``), 0 .. 2.
    compliance_friction : str
        Where a compliant axis's friction and viscous damping ``B`` act: ``"motor"`` (the
        default: screw bearings, nut and motor, the usual reduction of a ball-screw axis) or
        ``"load"`` (a belt's or a long screw's carriage on its guides; the friction at the
        load's position). The actuator force, the load force and the cogging stay on the
        motor.
    compliance_damping_motor_share : float
        With ``compliance_friction = "load"``: the share of the viscous damping ``B`` on the
        motor (its bearings, the pulleys), the rest on the load; 0 (the default) puts all of it
        on the load. Ignored with the friction on the motor. 0 .. 1.
    backlash_load_fraction : float
        Two bodies across the backlash gap: the share ``r = m_L / M`` of the mass that is the
        load (table). The friction acts on the load; the damping is split as the mass is;
        the actuator force, the load force and the cogging act on the motor. Inside the gap
        the motor moves alone and the load coasts until its friction stops it; the gap
        closes in an inelastic impact. 0 (the default) keeps the play operator (the limit of
        a massless load). At most 0.95; not with a compliant axis.
    """

    backlash: float = 0.0
    measurement: str = "motor"
    cogging_amplitude: float = 0.0
    cogging_period: float = 5.0e-3
    cogging_phase: float = 0.0
    cogging_harmonics: tuple[float, ...] = ()
    cogging_harmonic_phases: tuple[float, ...] = ()
    friction_gradient: float = 0.0
    friction_gradient_center: float = 0.0
    coulomb_asymmetry: float = 0.0
    viscous_asymmetry: float = 0.0
    friction_variation: float = 0.0
    friction_variation_period: float = 0.05
    friction_variation_phase: float = 0.0
    friction_profile: tuple[float, ...] = ()
    friction_profile_start: float = 0.0
    friction_profile_span: float = 0.0
    thermal_drift: float = 0.0
    thermal_time_constant: float = 600.0
    thermal_heating_speed: float = 0.0
    thermal_strain: float = 0.0
    thermal_strain_origin: float = 0.0
    quantization: float = 0.0
    noise_std: float = 0.0
    delay_samples: int = 0
    current_noise_std: float = 0.0
    compliance_load_fraction: float = 0.0
    compliance_frequency: float = 50.0
    compliance_damping: float = 0.05
    backlash_load_fraction: float = 0.0
    compliance_friction: str = "motor"
    compliance_damping_motor_share: float = 0.0

    def __post_init__(self) -> None:
        check_range("backlash", self.backlash, 0.0, 1e-3, "m")
        check_choice("measurement", self.measurement, ("motor", "table"))
        check_nonneg("cogging_amplitude", self.cogging_amplitude, "N")
        check_positive("cogging_period", self.cogging_period, "m")
        check_finite("cogging_phase", self.cogging_phase)
        self._check_harmonics()
        check_range("friction_gradient", self.friction_gradient, -1.0, 1.0, "1/m")
        check_finite("friction_gradient_center", self.friction_gradient_center)
        check_finite("coulomb_asymmetry", self.coulomb_asymmetry)
        check_finite("viscous_asymmetry", self.viscous_asymmetry)
        check_range("friction_variation", self.friction_variation, 0.0, 0.9)
        check_positive("friction_variation_period", self.friction_variation_period, "m")
        check_finite("friction_variation_phase", self.friction_variation_phase)
        self._check_profile()
        check_range("thermal_drift", self.thermal_drift, -1e-3, 1e-3, "m")
        check_positive("thermal_time_constant", self.thermal_time_constant, "s")
        check_nonneg("thermal_heating_speed", self.thermal_heating_speed, "m/s")
        check_range("thermal_strain", self.thermal_strain, -1e-3, 1e-3)
        check_finite("thermal_strain_origin", self.thermal_strain_origin)
        check_range("quantization", self.quantization, 0.0, 0.1, "m")
        check_range("noise_std", self.noise_std, 0.0, 1e-4, "m")
        check_int("delay_samples", self.delay_samples, 0, K.DELAY_MAX)
        check_range("current_noise_std", self.current_noise_std, 0.0, 100.0, "A")
        check_range("compliance_load_fraction", self.compliance_load_fraction, 0.0, 0.95)
        check_range("compliance_frequency", self.compliance_frequency, 0.1, 1.0e5, "Hz")
        check_range("compliance_damping", self.compliance_damping, 0.0, 2.0)
        check_range("backlash_load_fraction", self.backlash_load_fraction, 0.0, 0.95)
        check_choice("compliance_friction", self.compliance_friction, ("motor", "load"))
        check_range("compliance_damping_motor_share", self.compliance_damping_motor_share, 0.0,
                    1.0)
        if self.backlash_load_fraction > 0.0 and self.compliance_load_fraction > 0.0:
            raise ValueError(
                f"backlash_load_fraction={self.backlash_load_fraction:g} with "
                f"compliance_load_fraction={self.compliance_load_fraction:g}: expected one of "
                "the two (a two-body backlash on a compliant axis is not modelled)")

    def _check_harmonics(self) -> None:
        """At most two harmonic amplitudes (N, not negative) and as many phases or none."""
        amps = _numbers("cogging_harmonics", self.cogging_harmonics, 2)
        phases = _numbers("cogging_harmonic_phases", self.cogging_harmonic_phases, 2)
        for i, a in enumerate(amps):
            check_nonneg(f"cogging_harmonics[{i}]", a, "N")
        if phases and len(phases) != len(amps):
            raise ValueError(f"cogging_harmonic_phases: {len(phases)} phases for "
                             f"{len(amps)} harmonics, expected one per harmonic or none")
        object.__setattr__(self, "cogging_harmonics", amps)
        object.__setattr__(self, "cogging_harmonic_phases", phases)

    def _check_profile(self) -> None:
        """The friction profile: a sequence of at most ``PD_MAX_KNOTS`` changes within
        ``PD_LEVEL_RANGE`` (-0.9 .. 2),
        a finite start and, with two knots or more, a positive span."""
        knots = _numbers("friction_profile", self.friction_profile, PL.PD_MAX_KNOTS)
        values = tuple(check_range(f"friction_profile[{i}]", v, *PL.PD_LEVEL_RANGE)
                       for i, v in enumerate(knots))
        # a TOML array arrives as a list: stored as a tuple, so the section stays hashable
        object.__setattr__(self, "friction_profile", values)
        check_finite("friction_profile_start", self.friction_profile_start)
        if len(values) >= 2:
            check_positive("friction_profile_span", self.friction_profile_span, "m")
        else:
            check_nonneg("friction_profile_span", self.friction_profile_span, "m")
