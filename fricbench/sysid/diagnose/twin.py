"""The identified model as a Gymnasium env: ``fricbench diagnose RUN.csv --env-out TWIN.toml``.

:func:`twin_spec` turns a closed-loop diagnosis (:class:`~.diagnosis.DiagnosisResult`) into an
env spec of the format of ``envs/*.toml`` (:mod:`fricbench.gym.specs`): the identified plant,
its effects and the run's controller, in SI units. With the spec's folder on
``FRICBENCH_ENV_PATH``, ``gym.make(ID)`` runs the twin and ``fricbench bench --envs ID`` ranks
compensators on it; ``fricbench simulate --env ID --reference-csv RUN.csv`` replays the run's
reference through it, to check the twin against the measurement.

What goes where:

* the plant row (:mod:`fricbench.axis.plant`) becomes the ``[axis]`` tables through
  :data:`PLANT_PLACES`, one entry per plant column; a column the diagnosis set that has no place
  there is refused by name (a new plant column needs one entry), and the written axis is
  packed again and compared with the identified row column by column;
* forces: the diagnosis works in the effort's unit; ``effort_gain`` (N per effort unit, 1 when
  the effort is a force in N) converts them to newtons. The effort itself stays the drive's
  command (the "current" of ``[axis.controller]``, ``kt = effort_gain``); a run without an effort
  is modelled per unit mass, and the twin gets the mass ``mass`` (kg, default 1);
* the controller: a law identified from the effort (ARX) becomes ``law = "linear"``, its
  look-ahead taps on the reference folded into gains on the reference position, velocity and
  acceleration (exact for a reference of constant acceleration over the look-ahead), its past
  taps kept; a cascade fitted to the position becomes the env's cascade, a PID position loop
  the env's linear law (its difference equation, exact);
* the task: the standard trajectories scaled to the run's stroke, feed and acceleration, and
  the observation and reward scaled to its tracking error, speeds and forces.

An open-loop diagnosis identifies no controller: it has no twin (the command refuses
``--env-out`` with ``--open-loop``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from dataclasses import asdict
from typing import Any

import numpy as np

from fricbench.axis import Axis, Effects
from fricbench.axis import kernel as K
from fricbench.axis import plant as PL
from fricbench.gym.specs import ENV_ID_FORM, ENV_ID_PATTERN
from fricbench.sysid.diagnose.controllers import ArxController, CascadeController
from fricbench.sysid.diagnose.effects import describe_parameters

__all__ = ["ENV_ID_PATTERN", "PLANT_PLACES", "TwinError", "check_env_id", "twin_spec",
           "twin_toml"]


_F = "force"  # scaled by the effort gain (N per effort unit)
_SCALED = (_F,)

# plant column -> where an Axis holds it: (section, field, scaling) or a note why the env sets
# it itself. Columns holding forces (or forces per velocity, per mass) are scaled to newtons.
# A new plant column (a compliance, say) needs one entry here.
PLANT_PLACES: Mapping[str, tuple[str, str, str] | str] = {
    "ts": "the run's sample time (controller.ts)",
    "n_substeps": "the diagnosis's substeps (controller.n_substeps)",
    "mass": ("mechanics", "mass", _F),
    "damping": ("mechanics", "damping", _F),
    "kt": "the effort gain (controller.kt)",
    "i_max": "the drive's limit (controller.i_max)",
    "delay_samples": ("effects", "delay_samples", ""),
    "friction_kind": "static friction: friction.id = 'stribeck'",
    "fc": ("friction", "fc", _F),
    "dfc": ("effects", "coulomb_asymmetry", _F),
    "fs_excess": ("friction", "fs", _F),  # fs = fc + fs_excess
    "vs": ("friction", "vs", ""),
    "delta": ("friction", "delta", ""),
    "fv": ("friction", "fv", _F),
    "dB": ("effects", "viscous_asymmetry", _F),
    "sigma0": "dynamic friction: never identified by the diagnosis",
    "sigma1": "dynamic friction: never identified by the diagnosis",
    "offset": ("mechanics", "load", _F),
    "cog_sin": ("effects", "cogging_amplitude", _F),  # with cog_cos: amplitude and phase
    "cog_cos": ("effects", "cogging_phase", _F),
    "cog_period": ("effects", "cogging_period", ""),
    "pd_gradient": ("effects", "friction_gradient", ""),
    "pd_sin": ("effects", "friction_variation", ""),  # with pd_cos: amplitude and phase
    "pd_cos": ("effects", "friction_variation_phase", ""),
    "pd_period": ("effects", "friction_variation_period", ""),
    "pd_center": ("effects", "friction_gradient_center", ""),
    "backlash": ("effects", "backlash", ""),
    "thermal_amplitude": ("effects", "thermal_drift", ""),
    "thermal_tau": ("effects", "thermal_time_constant", ""),
    "quantization": "the sensor step the diagnosis detected (effects.quantization)",
    "noise_std": "left at 0: the bench adds its own encoder noise",
    "measure_table": ("effects", "measurement", ""),
    "compliance_load_fraction": ("effects", "compliance_load_fraction", ""),
    "compliance_frequency": ("effects", "compliance_frequency", ""),
    "compliance_damping": ("effects", "compliance_damping", ""),
    "log_motor": "the logged side: an env observes the load (table) position",
    "thermal_heating_speed": ("effects", "thermal_heating_speed", ""),
    "backlash_load_fraction": ("effects", "backlash_load_fraction", ""),
    "compliance_friction_load": ("effects", "compliance_friction", ""),
    "compliance_b_motor_share": ("effects", "compliance_damping_motor_share", ""),
    "pd_profile_start": ("effects", "friction_profile_start", ""),
    "pd_profile_span": ("effects", "friction_profile_span", ""),
    "pd_profile_knots": ("effects", "friction_profile", ""),  # the knots' values, as a list
    **{f"pd_profile_{i}": ("effects", "friction_profile", "")
       for i in range(PL.PD_MAX_KNOTS)},
    # with their cosines: amplitudes and phases, as lists (written with cog_h2_sin)
    "cog_h2_sin": ("effects", "cogging_harmonics", _F),
    "cog_h2_cos": ("effects", "cogging_harmonic_phases", _F),
    "cog_h3_sin": ("effects", "cogging_harmonics", _F),
    "cog_h3_cos": ("effects", "cogging_harmonic_phases", _F),
    "thermal_strain": ("effects", "thermal_strain", ""),
    "thermal_strain_origin": ("effects", "thermal_strain_origin", ""),
}

# pairs stored as sine and cosine coefficients in the plant row, as amplitude and phase in an
# Axis: A sin(k x + phi) = A cos(phi) sin(k x) + A sin(phi) cos(k x)
_POLAR = {"cog_sin": "cog_cos", "pd_sin": "pd_cos"}

# an effect's columns whose off value makes the others irrelevant (their defaults are kept)
_ONLY_WITH = {"cog_period": ("cog_sin", "cog_cos", "cog_h2_sin", "cog_h2_cos", "cog_h3_sin",
                            "cog_h3_cos"), "pd_period": ("pd_sin", "pd_cos"),
              "thermal_tau": ("thermal_amplitude", "thermal_strain"),
              "thermal_heating_speed": ("thermal_amplitude", "thermal_strain"),
              "vs": ("fs_excess",),
              "thermal_strain_origin": ("thermal_strain",),
              "delta": ("fs_excess",), "pd_center": ("pd_gradient",),
              "compliance_frequency": ("compliance_load_fraction",),
              "compliance_damping": ("compliance_load_fraction",),
              "backlash_load_fraction": ("backlash",),
              "compliance_friction_load": ("compliance_load_fraction",),
              "compliance_b_motor_share": ("compliance_friction_load",),
              "pd_profile_start": ("pd_profile_knots",), "pd_profile_span": ("pd_profile_knots",),
              **{f"pd_profile_{i}": ("pd_profile_knots",) for i in range(PL.PD_MAX_KNOTS)}}

class TwinError(ValueError):
    """The diagnosis cannot be written as an env (the message names why)."""


def check_env_id(env_id: str) -> str:
    """``env_id`` if it is a valid env id ``namespace/Name-vN``
    (:data:`fricbench.gym.specs.ENV_ID_PATTERN`), else ``ValueError``."""
    if not isinstance(env_id, str) or not ENV_ID_PATTERN.fullmatch(env_id):
        raise ValueError(f"env_id={env_id!r}: expected {ENV_ID_FORM}")
    return env_id


def _fold_reference(law: ArxController, ts: float) -> tuple[list[float], list[float]]:
    """The law's reference taps as the env's law holds them: ``[k_x, k_v, k_a]`` and the gains
    ``g_1 .. g_m`` on the past reference ``x_r[k-1] .. x_r[k-m]``.

    ``sum_j b_j x_r[k + lead - j]``: the present and past taps are kept; the look-ahead taps
    (``d = lead - j > 0`` samples ahead) are folded into the present position, velocity and
    acceleration, ``x_r[k + d] = x_r + d ts v_r + (d ts)^2 / 2 a_r``, exact for a reference of
    constant acceleration over ``lead`` samples.
    """
    b = np.asarray(law.b, dtype=float)
    d = law.lead - np.arange(b.shape[0])
    ahead = d > 0
    dt = ts * d[ahead]
    kx = float(np.sum(b[ahead]) + np.sum(b[d == 0]))
    kv = float(np.sum(b[ahead] * dt))
    ka = float(np.sum(b[ahead] * dt * dt) / 2.0)
    past = [float(b[j]) for j in np.flatnonzero(d < 0)]  # d = -1, -2, ... in order
    return [kx, kv, ka], past


def _controller(ctrl: ArxController | CascadeController, *, ts: float, n_sub: int,
                gain: float, mass_si: float, i_max: float) -> dict[str, Any]:
    base: dict[str, Any] = {"ts": _sample_time(ts), "n_substeps": n_sub, "i_max": i_max}
    if isinstance(ctrl, ArxController):
        ref, past = _fold_reference(ctrl, ts)
        if (ctrl.a.shape[0] > K.LAW_NA_MAX or ctrl.c.shape[0] > K.LAW_NC_MAX
                or len(past) > K.LAW_NR_MAX):
            raise TwinError(f"the identified law has {ctrl.a.shape[0]} recursion, "
                            f"{ctrl.c.shape[0]} position and {len(past)} past-reference "
                            f"coefficients: the env's law holds at most {K.LAW_NA_MAX}, "
                            f"{K.LAW_NC_MAX} and {K.LAW_NR_MAX} (fricbench.axis.kernel)")
        return {**base, "kt": gain, "law": "linear", "law_reference": ref,
                "law_reference_history": past,
                "law_position": [float(v) for v in ctrl.c],
                "law_recursion": [float(v) for v in ctrl.a]}
    if ctrl.is_pid or ctrl.vel_pole != 0.0:
        # a PID position loop is no env cascade: its difference equation (a filter of the
        # reference position alone) is the env's linear law, per unit mass times the mass (a
        # force, N, at kt = 1 N/A)
        a, c, t = ctrl.difference_form(ts)
        return {**base, "kt": 1.0, "law": "linear",
                "law_reference": [float(mass_si * t[0]), 0.0, 0.0],
                "law_reference_history": [float(mass_si * v) for v in t[1:]],
                "law_position": [float(mass_si * v) for v in c],
                "law_recursion": [float(v) for v in a]}
    # u = wv (e_v + I) per unit mass: the env's i = kv (e_v + I) with kt = 1 N/A
    return {**base, "kt": 1.0, "kp": ctrl.kp, "kvff": ctrl.kvff, "kaff": ctrl.kaff,
            "kv": ctrl.wv * mass_si, "ti": (1.0 / ctrl.ki) if ctrl.ki > 0 else 0.0}


def _sample_time(ts: float) -> float:
    """The run's mean sample time, snapped to 3 digits when within 1e-4 of them (a logger's
    clock jitter: EMPS's 0.000999984 s is its 1 ms)."""
    snapped = float(f"{ts:.3g}")
    return snapped if abs(snapped - ts) <= 1e-4 * ts else float(f"{ts:.12g}")


def _axis_tables(p: np.ndarray, gain: float) -> dict[str, dict[str, Any]]:
    """The ``[axis]`` tables holding plant row ``p`` (diagnosis units) in SI."""
    si = np.array(p, dtype=float)
    missing = [n for n in PL.PLANT_NAMES if n not in PLANT_PLACES]
    if missing:
        raise TwinError(f"plant columns {missing} have no place in an env spec: add them to "
                        "fricbench.sysid.diagnose.twin.PLANT_PLACES")
    out: dict[str, dict[str, Any]] = {"mechanics": {}, "friction": {"id": "stribeck"},
                                      "effects": {}}
    if int(p[PL.FKIND]) != PL.KIND_STATIC:
        raise TwinError(f"friction_kind={int(p[PL.FKIND])}: the twin writes static friction "
                        "laws only")
    for i, name in enumerate(PL.PLANT_NAMES):
        place = PLANT_PLACES[name]
        if isinstance(place, str) or name in _POLAR.values() or _unused(p, name):
            continue
        section, key, scale = place
        value = float(si[i]) * (gain if scale in _SCALED else 1.0)
        if name in _POLAR:
            j = PL.PLANT_NAMES.index(_POLAR[name])
            other = float(si[j]) * (gain if scale in _SCALED else 1.0)
            if value != 0.0 or other != 0.0:
                out[section][key] = math.hypot(value, other)
                out[section][PLANT_PLACES[_POLAR[name]][1]] = math.atan2(other, value)  # type: ignore[index]
        elif name == "fs_excess":
            out[section][key] = float(si[PL.FC]) * gain + value
        elif name == "measure_table":
            out[section][key] = "table" if value > 0.5 else "motor"
        elif name == "compliance_friction_load":
            out[section][key] = "load" if value > 0.5 else "motor"
        elif name == "delay_samples":
            out[section][key] = int(value)
        elif name == "pd_profile_knots":
            out[section][key] = tuple(float(si[PL.PD_KNOT0 + j]) for j in range(int(value)))
        elif name.startswith("pd_profile_") and name[len("pd_profile_"):].isdigit():
            continue  # written with pd_profile_knots
        elif name == "cog_h2_sin":
            out[section].update(_harmonics(si, gain))
        elif name.startswith("cog_h"):
            continue  # written with cog_h2_sin
        else:
            out[section][key] = value
    # an effect at its default (off) needs no line
    defaults = asdict(Effects())
    out["effects"] = {k: v for k, v in out["effects"].items() if v != defaults[k]}
    return out


def _harmonics(si: np.ndarray, gain: float) -> dict[str, tuple[float, ...]]:
    """The cogging's harmonics as the env's amplitudes and phases (the last zero ones left
    out): ``A sin(k x + phi) = A cos(phi) sin(k x) + A sin(phi) cos(k x)``."""
    pairs = [(float(si[c]) * gain, float(si[c + 1]) * gain)
             for c in (PL.COG_H2_SIN, PL.COG_H3_SIN)]
    while pairs and pairs[-1] == (0.0, 0.0):
        pairs.pop()
    return {"cogging_harmonics": tuple(math.hypot(a, b) for a, b in pairs),
            "cogging_harmonic_phases": tuple(math.atan2(b, a) for a, b in pairs)}


def _unused(p: np.ndarray, name: str) -> bool:
    """Whether column ``name`` is irrelevant because the effect it shapes is off."""
    owners = _ONLY_WITH.get(name, ())
    return bool(owners) and all(p[PL.PLANT_NAMES.index(o)] == 0.0 for o in owners)


def _check_round_trip(axis: Axis, p: np.ndarray, gain: float) -> None:
    """Every plant column the diagnosis set survives into the env's packed row."""
    packed = axis.pack()[: PL.N_PLANT]
    for i, name in enumerate(PL.PLANT_NAMES):
        place = PLANT_PLACES[name]
        if isinstance(place, str):
            continue
        if _unused(p, name):
            continue
        want = float(p[i]) * (gain if place[2] in _SCALED else 1.0)
        if not math.isclose(packed[i], want, rel_tol=1e-9, abs_tol=1e-12 * max(1.0, abs(want))):
            raise TwinError(f"plant column {name!r}={want:g} is {packed[i]:g} in the written "
                            "env: its place in fricbench.sysid.diagnose.twin.PLANT_PLACES is "
                            "wrong")


def twin_spec(result: Any, env_id: str, *, effort_gain: float | None = None,
              mass: float = 1.0, effort_limit: float | None = None,
              description: str | None = None) -> tuple[dict[str, Any], list[str]]:
    """The env spec of a closed-loop diagnosis, and the comment lines to write above it.

    Parameters
    ----------
    result : DiagnosisResult
        A closed-loop diagnosis (:func:`fricbench.sysid.diagnose.diagnose`).
    env_id : str
        Id of the twin, ``fricbench/Name-vN``.
    effort_gain : float, optional
        Newtons per unit of the run's effort (the drive's force constant). Default 1 when the
        effort is a force in N; required for another effort unit.
    mass : float
        Moving mass, kg, of a run diagnosed without an effort (forces per unit mass).
    effort_limit : float, optional
        The drive's limit in the effort's unit (default: the clip level detected in the run,
        else ten times the largest effort of the run).
    description : str, optional
        The env's description (default: where it comes from and what it does not model).

    Returns
    -------
    spec : dict
        ``id``, ``description``, ``axis``, ``task`` tables, checked by building the axis.
    comments : list of str
        Where each number comes from, for the file's head.

    Raises
    ------
    TwinError
        The model cannot be written as an env (named why).
    ValueError
        ``env_id``, ``effort_gain``, ``mass`` or ``effort_limit`` malformed.
    """
    check_env_id(env_id)
    model = result.final
    prep = result.prep
    fu = result.force_unit
    ctrl = model.controller
    if result.mode == "effort":
        if effort_gain is None:
            if fu != "N":
                raise ValueError(f"effort_gain=None: the effort is in {fu}; give the newtons "
                                 f"per {fu} of the drive (--effort-gain) to write the twin in SI")
            effort_gain = 1.0
        gain = _positive("effort_gain", effort_gain)
        mass_si = float(model.plant[PL.M]) * gain
        unit_note = (f"effort in {fu}, {gain:g} N per {fu} (controller.kt); forces converted "
                     "to N")
    else:
        gain = _positive("mass", mass)
        mass_si = gain
        why = ("the effort's law was set aside (see the diagnosis's warnings)"
               if result.run.u is not None else "no effort in the run")
        unit_note = (f"{why}: the model is per unit mass, written for a mass of "
                     f"{gain:g} kg (every force scales with it)")
    peak = (float(np.max(np.abs(prep.u))) if prep.u is not None
            else float(np.max(np.abs(prep.af))))
    if effort_limit is not None:
        i_max, limit_note = _positive("effort_limit", effort_limit), "stated"
    elif prep.saturation is not None:
        i_max, limit_note = float(prep.saturation.level), "the clip level detected in the run"
    elif math.isfinite(float(model.plant[PL.IMAX])):
        i_max = float(model.plant[PL.IMAX])
        limit_note = "the drive limit identified from the position"
    else:
        i_max = 10.0 * peak
        limit_note = "10 x the run's largest effort (no clipping seen; not identified)"
    if result.mode != "effort":
        i_max *= gain  # a force, N, at kt = 1 N/A
    tables = _axis_tables(model.plant, gain)
    # the loop's own period: a loop identified faster than the log runs at its rate
    tables["controller"] = _controller(ctrl, ts=prep.inputs.loop_ts, n_sub=prep.n_sub, gain=gain,
                                       mass_si=mass_si, i_max=i_max)
    quantum = float(prep.noise.quantum)
    if 0.0 < quantum <= 1e-4:
        tables["effects"]["quantization"] = quantum
    task = _task(result, tables, gain)
    axis_t = {k: tables[k] for k in ("controller", "mechanics", "friction", "effects")
              if tables[k]}
    try:
        axis = Axis.from_dict(axis_t)
    except (TypeError, ValueError) as exc:
        raise TwinError(f"the identified model is not a valid env axis: {exc}") from None
    _check_round_trip(axis, model.plant, gain)
    effects = result.effects
    found = ", ".join(effects) if effects else "no effect beyond the linear model"
    desc = description or (
        f"Twin of the axis logged in {os.path.basename(result.run.source)}, identified by "
        f"fricbench diagnose ({found}); not "
        "modelled: anything the diagnosis did not find, the plant beyond the logged speeds and "
        "forces, and a controller other than the run's.")
    pos = result.train.position()
    comments = [
        "Digital twin written by 'fricbench diagnose --env-out' from "
        f"{os.path.basename(result.run.source)}",
        f"({result.run.n_samples} samples, mean step {prep.ts:.9g} s; controller.ts "
        f"{_sample_time(prep.inputs.loop_ts):g} s"
        + (f", the loop identified {prep.inputs.n_loop} times faster than the log"
           if prep.inputs.n_loop > 1 else "") + ").",
        f"Units: SI inside (m, s, kg, N); {unit_note}.",
        f"Controller: {result.laws.get('train', '')}"
        + (" (law = 'linear': its look-ahead reference taps folded into gains on x_r, v_r, a_r)"
           if isinstance(ctrl, ArxController) else " (the env's cascade)") + ".",
        *(["The diagnosis ran this law in positional form, its integral clamped while the "
           "drive clips; the env's linear law runs its velocity form, which recurses on the "
           "clipped command: the same law until the drive clips, and while it clips both keep "
           "the integral from winding up, by different rules."]
          if isinstance(ctrl, ArxController) and ctrl.clamped else []),
        f"Drive limit controller.i_max: {limit_note}.",
        f"Free-run position error of the diagnosis on its run: rms {pos['rms_after']:.4g} m "
        f"(linear model {pos['rms_before']:.4g} m).",
        "Effects found: " + ("none" if not effects else "; ".join(
            f"{e} ({_params(e, model.plant, fu)})" for e in effects)) + f" (forces in {fu}).",
    ]
    return {"id": env_id, "description": desc, "axis": axis_t, "task": task}, comments


def _params(effect: str, p: np.ndarray, fu: str) -> str:
    return ", ".join(f"{k}={v:.4g}" for k, v in describe_parameters(effect, p, fu).items())


def _positive(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name}={value!r}: expected a positive finite number")
    return float(value)


def _task(result: Any, tables: dict[str, dict[str, Any]], gain: float) -> dict[str, Any]:
    """Standard trajectories at the run's stroke, feed and acceleration; scales from the run."""
    prep = result.prep
    inp = prep.inputs
    stroke = max(float(np.ptp(inp.xr)), 1e-4)
    feed = max(float(np.max(np.abs(inp.vr))), 1e-4)
    accel = max(float(np.percentile(np.abs(inp.ar), 99.5)), 1e-3)
    err = float(np.sqrt(np.mean((inp.xr - prep.x) ** 2)))
    fr, mech, eff = tables["friction"], tables["mechanics"], tables["effects"]
    breakaway = (fr.get("fs", 0.0) + 0.5 * abs(eff.get("coulomb_asymmetry", 0.0))
                 + abs(mech.get("load", 0.0)))
    force_peak = (float(np.max(np.abs(prep.u))) * gain if prep.u is not None
                  else float(np.max(np.abs(prep.af))) * gain)
    action = max(2.0 * breakaway, 0.01 * force_peak, 1e-6)
    r = (lambda v: float(f"{v:.3g}"))
    return {
        "trajectories": [
            {"id": "m_serial", "stroke": r(0.8 * stroke), "feed": r(0.8 * feed),
             "accel": r(accel)},
            {"id": "s_curve", "distance": r(0.8 * stroke), "feed": r(feed), "accel": r(accel)},
            "reversal_sine",
        ],
        "action": "force",
        "action_scale": r(action),
        "observation": {"error_scale": r(max(err, 1e-9)), "position_scale": r(0.5 * stroke),
                        "velocity_scale": r(0.5 * feed), "acceleration_scale": r(accel),
                        "force_scale": r(max(force_peak, 1e-6))},
        "reward": {"error_scale": r(max(err, 1e-9))},
    }


# -- TOML --------------------------------------------------------------------------------------
def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{k} = {_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"{v!r}: not a TOML value")


def _table(name: str, table: Mapping[str, Any], lines: list[str]) -> None:
    scalars = {k: v for k, v in table.items() if not isinstance(v, Mapping)}
    lines.append(f"\n[{name}]")
    lines += [f"{k} = {_value(v)}" for k, v in scalars.items()]
    for k, v in table.items():
        if isinstance(v, Mapping):
            _table(f"{name}.{k}", v, lines)


def twin_toml(spec: Mapping[str, Any], comments: list[str]) -> str:
    """The text of a spec file: comment lines, ``id``, ``description``, then the tables."""
    lines = [f"# {c}" for c in comments]
    lines += [f"id = {_value(spec['id'])}", f"description = {_value(spec['description'])}"]
    for key in ("benchmark", "fit_on"):
        if key in spec:
            lines.append(f"{key} = {_value(spec[key])}")
    for section in ("controller", "mechanics", "friction", "effects"):
        if section in spec["axis"]:
            _table(f"axis.{section}", spec["axis"][section], lines)
    _table("task", spec["task"], lines)
    return "\n".join(lines) + "\n"


def write_twin(path: str, spec: Mapping[str, Any], comments: list[str],
               write: Callable[[str, str], None] | None = None) -> None:
    """Write the spec file atomically (:func:`fricbench._atomic.atomic_write`)."""
    from fricbench._atomic import atomic_write

    (write or atomic_write)(path, twin_toml(spec, comments))
