"""Undeclared effects: runs of the project's simulator with an effect diagnose is not told about.

Each case draws (seeded) an axis, a reference and one effect over realistic ranges:

* the axis: mass 100..600 kg, velocity-loop bandwidth 250..500 rad/s, position gain 25..45 % of
  it, integral time 4..10 loop time constants, velocity feedforward 0.9..1.1, damping 50..300
  N s/m, Stribeck friction with Coulomb level 0.3..1 m/s^2 times the mass, breakaway
  1.1..1.5 times that, Stribeck velocity 1..4 mm/s; linear-scale step 20..100 nm, white
  noise 20..150 nm;
* the reference: a random sequence of smooth moves (2..50 mm/s), sine blocks and dwells over a
  30 mm stroke, 16 s at 1 kHz;
* the effect (motor-side encoder, logged table position): cogging 0.2..0.8 times the Coulomb
  level with a 2..8 mm period; backlash 3..15 um; thermal growth 4..15 um with a 3..15 s
  time constant; friction varying by 30..80 % along the stroke with a 12..30 mm period.

An effect so small that it cannot be seen in the position (its noise-free signature below
twice the noise floor of a free-run prediction) is redrawn: no method can name it, and the
issue asks to say "nothing left to explain" there. The control runs have friction only.

Diagnose gets the position only (no effort column), the hardest and most general case. It must
name the effect present, must not name effects that are absent (anything but friction and the
effect), and must cut the position rms error at least 2x against the linear model or bring it
within 1.5x of the noise floor.
"""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.sysid.diagnose import diagnose
from fricbench.sysid.io import validate_arrays
from fricbench.trajectories.base import Reference

FRICTION = {"coulomb_friction", "stribeck_friction"}
EFFECT_NAME = {"cogging": "cogging", "backlash": "backlash", "thermal": "thermal_drift",
               "posdep": "position_dependent_friction", "control": None}


def random_reference(rng: np.random.Generator, duration: float = 16.0, ts: float = 1e-3,
                     stroke: float = 0.03) -> Reference:
    """Smooth moves, sine blocks and dwells within +-stroke/2."""
    pieces = [np.zeros(int(0.2 / ts))]
    x, lim = 0.0, stroke / 2
    while sum(len(p) for p in pieces) * ts < duration - 1.0:
        kind = rng.choice(["move", "move", "sine", "dwell"])
        if kind == "move":
            target = rng.uniform(-lim, lim)
            dist = target - x
            if abs(dist) < 1e-4:
                continue
            feed = np.exp(rng.uniform(np.log(2e-3), np.log(0.05)))
            n = int(max(1.5 * abs(dist) / feed, 0.05) / ts)
            tau = np.arange(1, n + 1) / n
            # cycloidal move: smooth velocity and acceleration
            seg = x + dist * (tau - np.sin(2 * np.pi * tau) / (2 * np.pi))
            x = target
        elif kind == "sine":
            f = np.exp(rng.uniform(np.log(0.3), np.log(3.0)))
            amp = min(np.exp(rng.uniform(np.log(2e-4), np.log(lim / 2))), 0.04 / (2 * np.pi * f),
                      lim - abs(x))
            n = int(rng.integers(1, 4) / f / ts)
            tt = np.arange(1, n + 1) * ts
            seg = x + amp * np.sin(2 * np.pi * f * tt) * np.sin(np.pi * tt / tt[-1]) ** 2
        else:
            seg = np.full(int(rng.uniform(0.05, 0.5) / ts), x)
        pieces.append(seg)
        pieces.append(np.full(int(rng.uniform(0.0, 0.3) / ts), x))
    xs = np.concatenate(pieces)
    n = int(duration / ts)
    xs = np.concatenate([xs, np.full(max(0, n - len(xs)), xs[-1])])[:n]
    return Reference.from_positions(np.arange(n) * ts, xs)


def random_axis(rng: np.random.Generator) -> Axis:
    """A stable cascade axis with Stribeck friction, encoder quantisation and noise."""
    mass = rng.uniform(100, 600)
    wv = rng.uniform(250, 500)
    kt = 600.0
    fc = rng.uniform(0.3, 1.0) * mass
    axis = Axis().with_controller(kp=rng.uniform(0.25, 0.45) * wv, kv=wv * mass / kt,
                                  ti=rng.uniform(4, 10) / wv, kvff=rng.uniform(0.9, 1.1), kt=kt)
    axis = axis.with_mechanics(mass=mass, damping=rng.uniform(50, 300))
    axis = axis.with_friction("stribeck", fc=fc, fs=fc * rng.uniform(1.1, 1.5),
                              vs=rng.uniform(1e-3, 4e-3))
    return axis.with_effects(noise_std=rng.uniform(0.02e-6, 0.15e-6),
                             quantization=float(rng.choice([2e-8, 5e-8, 1e-7])))


def add_effect(axis: Axis, kind: str, rng: np.random.Generator) -> Axis:
    """The axis with one undeclared effect drawn at random."""
    fc = axis.friction.fc  # type: ignore[attr-defined]
    if kind == "cogging":
        return axis.with_effects(cogging_amplitude=rng.uniform(0.2, 0.8) * fc,
                                 cogging_period=rng.uniform(2e-3, 8e-3),
                                 cogging_phase=rng.uniform(0, 2 * np.pi))
    if kind == "backlash":
        return axis.with_effects(backlash=rng.uniform(3e-6, 15e-6))
    if kind == "thermal":
        return axis.with_effects(thermal_drift=rng.choice([-1.0, 1.0]) * rng.uniform(4e-6, 15e-6),
                                 thermal_time_constant=rng.uniform(3.0, 15.0))
    if kind == "posdep":
        return axis.with_effects(friction_variation=rng.uniform(0.3, 0.8),
                                 friction_variation_period=rng.uniform(0.012, 0.03),
                                 friction_variation_phase=rng.uniform(0, 2 * np.pi))
    return axis


def _clean(axis: Axis) -> Axis:
    return axis.with_effects(noise_std=0.0, quantization=0.0)


def draw_case(kind: str, seed: int) -> tuple[Axis, Reference, float]:
    """Axis, reference and the noise floor of a free-run prediction (m) of one case.

    The floor is the rms difference between the run and the same run without noise and
    quantisation: what a perfect deterministic model would still miss. The effect is redrawn
    (and after 5 tries the whole case) until its noise-free signature is at least twice that.
    """
    for attempt in range(10):
        rng = np.random.default_rng([seed, attempt])
        ref = random_reference(rng)
        base = random_axis(rng)
        y_clean = simulate(_clean(base), ref).x
        floor = float(np.sqrt(np.mean((simulate(base, ref, seed=seed).x - y_clean) ** 2)))
        for _ in range(5):
            axis = add_effect(base, kind, rng)
            if kind == "control":
                return axis, ref, floor
            signature = np.sqrt(np.mean((simulate(_clean(axis), ref).x - y_clean) ** 2))
            if signature >= 2.0 * floor:
                return axis, ref, floor
    raise RuntimeError(f"{kind} seed {seed}: no visible effect in 50 draws")


# Known misses, kept visible as strict xfails (the day one passes, its marker must go).
# posdep/12 was one while the plant move alone flipped a quantum of its data; it passes again
# with the library solvers, and since a runner-up restarts from its own fits of the previous
# step, on both OpenBLAS kernels tried (Haswell and SkylakeX: they round differently).
# cogging/12 (0.34 m/s^2 ripple, 3.3 mm period) was one until every step fitted cogging for
# real from several periods of the residual's spectrum (its linearised screen is unreliable
# through stick-slip). cogging/11 (rms cut only 1.7x, the final refit sensitive to rounding)
# was one until that same restart of a runner-up. tests/sysid/sweep_undeclared.py runs a wider
# sweep.
_KNOWN_MISSES: dict[tuple[str, int], str] = {}
CASES = [pytest.param(kind, seed, marks=pytest.mark.xfail(strict=True,
                                                          reason=_KNOWN_MISSES[(kind, seed)]))
         if (kind, seed) in _KNOWN_MISSES else (kind, seed)
         for kind in ("control", "cogging", "backlash", "thermal", "posdep")
         for seed in (11, 12)]


def check_case(kind: str, seed: int) -> tuple[list[str], dict[str, object]]:
    """Diagnose one case; the failures (empty when it passes) and the report."""
    axis, ref, floor = draw_case(kind, seed)
    res = simulate(axis, ref, seed=seed)
    run = validate_arrays(res.t, res.x_ref, res.x)
    out = diagnose(run).to_dict()
    effects = set(out["effects"])
    present = EFFECT_NAME[kind]
    allowed = FRICTION | ({present} if present else set())
    failures = []
    if effects - allowed:
        failures.append(f"{kind}/{seed}: named absent effects {effects - allowed}")
    if present is not None and present not in effects:
        failures.append(f"{kind}/{seed}: missed {present}, found {effects}")
    pos = out["position"]
    if pos["rms_after"] > max(0.5 * pos["rms_before"], 1.5 * floor):
        failures.append(f"{kind}/{seed}: rms {pos['rms_before']:.3g} -> "
                        f"{pos['rms_after']:.3g} m, floor {floor:.3g} m")
    return failures, out


@pytest.mark.parametrize(("kind", "seed"), CASES)
def test_undeclared_effect_is_found(kind: str, seed: int) -> None:
    failures, _ = check_case(kind, seed)
    assert not failures, "; ".join(failures)


def test_a_linear_axis_gets_no_effect() -> None:
    """Without friction or effects, nothing may be named (position only and with effort)."""
    rng = np.random.default_rng(5)
    ref = random_reference(rng, duration=8.0)
    axis = random_axis(rng).without_friction()
    res = simulate(axis, ref, seed=5)
    assert diagnose(validate_arrays(res.t, res.x_ref, res.x)).effects == []
    assert diagnose(validate_arrays(res.t, res.x_ref, res.x, res.u)).effects == []
