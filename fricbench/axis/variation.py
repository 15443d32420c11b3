"""The machine each benchmark seed runs on: a plant drawn around the env's nominal axis.

Nominally equal feed axes differ, and one axis changes with temperature, lubrication and wear:
the benchmark scores every compensator on several such machines, one per seed, rather than on
one idealised copy. Each seed draws its plant once (the same for every compensator, which
makes the seeds *paired*) from the distribution below, and adds measurement noise beside the
encoder quantisation. ``fricbench bench --nominal`` runs the env's nominal axis instead, noise
free: that is the axis of ``fricbench reproduce``, the docs' figures and the leaderboards before
plants were drawn.

Distribution (:class:`PlantVariation`, defaults in :data:`BENCH_VARIATION`): each parameter
is multiplied by ``exp(sigma z)`` with ``z`` standard normal truncated to ``|z| <= 2``
(log-normal, always positive, median the nominal value):

=====================  =======  ==============================================================
parameter              sigma    what varies it
=====================  =======  ==============================================================
friction level         0.20     ``fc``, ``fs`` (and ``fv`` when the model has one) together:
                                lubricant temperature and state, preload, wear
static excess          0.15     ``fs - fc`` on its own (breakaway after dwell, lubrication)
Stribeck velocity      0.25     ``vs`` (lubricant viscosity with temperature)
mass                   0.05     reflected mass (table load, workpiece)
damping                0.20     viscous damping ``B`` (lubricant viscosity with temperature)
=====================  =======  ==============================================================

Measurement noise: encoder noise of 0.1 um (standard deviation, about 0.4 of the 0.25 um
encoder step: edge jitter and interpolation noise) beside the quantisation, and a
current-measurement noise of 0.05 A (standard deviation, 0.33 % of the 15 A current limit: a few
steps of a 12-bit converter over +-30 A), which the drive's reported motor force carries
(30 N at ``kt`` = 600 N/A).

Sources and status: friction of machine axes is reported to change with temperature,
lubrication, load and wear (Armstrong-Helouvry, Dupont and Canudas de Wit, "A survey of models,
analysis tools and compensation methods for the control of machines with friction",
Automatica 30(7), 1994; Bittencourt and Gunnarsson, "Static friction in a robot joint:
modeling and identification of load and temperature effects", J. Dyn. Syst. Meas. Control
134(5), 2012, where the friction of one joint changes by tens of percent over its working
temperature range). The sigmas above and the noise levels are an engineering assumption in
that range, not a measurement of one machine: a spread of a few tens of percent between axes
and operating states, and sensor noise of a fraction of an encoder step and of a percent of
the current range.

What the compensators are told does not change with the seed: ``context.nominal_axis`` is the
env's nominal axis with the (known, datasheet) noise levels; the drawn friction, mass and
damping are only seen through the runs. Model compensators are fitted per seed on training
runs of that seed's plant (never on the scored run).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from fricbench._validation import check_nonneg, check_range
from fricbench.axis import Axis
from fricbench.friction import make_friction

__all__ = ["BENCH_VARIATION", "PLANT_SEED_TAG", "PlantVariation", "draw_plant", "nominal_told"]

PLANT_SEED_TAG = 0x504C41  # "PLA": keeps the plant's stream apart from the episode's seeds
TRUNCATION = 2.0
"""Largest ``|z|`` of a draw: factors within ``exp(+-2 sigma)``."""


@dataclass(frozen=True)
class PlantVariation:
    """Spread of the plant around the nominal axis, and the measurement noise.

    Parameters
    ----------
    friction_level : float
        Log-normal sigma of the common factor on the friction levels ``fc``, ``fs``, ``fv``.
    static_excess : float
        Log-normal sigma of a further factor on ``fs - fc``.
    stribeck_velocity : float
        Log-normal sigma of the factor on ``vs``.
    mass : float
        Log-normal sigma of the factor on the reflected mass.
    damping : float
        Log-normal sigma of the factor on the viscous damping.
    encoder_noise : float
        Standard deviation of the position measurement noise, m (``effects.noise_std``).
    current_noise : float
        Standard deviation of the current-measurement noise, A
        (``effects.current_noise_std``).
    """

    friction_level: float = 0.20
    static_excess: float = 0.15
    stribeck_velocity: float = 0.25
    mass: float = 0.05
    damping: float = 0.20
    encoder_noise: float = 1.0e-7
    current_noise: float = 0.05

    def __post_init__(self) -> None:
        for name in ("friction_level", "static_excess", "stribeck_velocity", "mass", "damping"):
            check_range(name, getattr(self, name), 0.0, 1.0)
        check_range("encoder_noise", self.encoder_noise, 0.0, 1e-4, "m")
        check_nonneg("current_noise", self.current_noise, "A")


BENCH_VARIATION = PlantVariation()
"""The distribution ``fricbench bench`` draws its plants from (see the module docstring)."""


def _factor(rng: np.random.Generator, sigma: float) -> float:
    z = float(rng.standard_normal())
    # exp(sigma z), z truncated to [-2, 2]
    return math.exp(sigma * max(-TRUNCATION, min(TRUNCATION, z)))


def nominal_told(axis: Axis, variation: PlantVariation = BENCH_VARIATION) -> Axis:
    """The nominal axis as compensators know it: its parameters, the variation's noise levels."""
    return axis.with_effects(noise_std=variation.encoder_noise,
                             current_noise_std=variation.current_noise)


def draw_plant(axis: Axis, seed: int, variation: PlantVariation = BENCH_VARIATION) -> Axis:
    """The plant of benchmark seed ``seed`` around the nominal ``axis``.

    The same ``(axis, seed, variation)`` gives the same plant, bit for bit; the draw order is
    fixed (friction level, static excess, Stribeck velocity, mass, damping).

    Parameters
    ----------
    axis : Axis
        The env's nominal axis.
    seed : int
        Benchmark seed, >= 0.
    variation : PlantVariation
        The distribution.

    Returns
    -------
    Axis
        ``axis`` with drawn friction, mass and damping and the variation's noise levels.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed={seed!r}: expected an integer >= 0")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), PLANT_SEED_TAG]))
    level = _factor(rng, variation.friction_level)
    excess = _factor(rng, variation.static_excess)
    vs_factor = _factor(rng, variation.stribeck_velocity)
    mass = _factor(rng, variation.mass)
    damping = _factor(rng, variation.damping)
    params = axis.friction.to_dict()
    fid = params.pop("id")
    if "fc" in params and "fs" in params:
        fc = params["fc"] * level
        params["fs"] = fc + (params["fs"] - params["fc"]) * level * excess
        params["fc"] = fc
    elif "fc" in params:
        params["fc"] *= level
    if "fv" in params:
        params["fv"] *= level
    if "vs" in params:
        params["vs"] *= vs_factor
    plant = replace(axis, friction=make_friction(fid, **params))
    plant = plant.with_mechanics(mass=axis.mechanics.mass * mass,
                                 damping=axis.mechanics.damping * damping)
    return nominal_told(plant, variation)
