"""The linear part of the axis (friction and effects off) as python-control systems.

:func:`closed_loop` is the loop of the continuous mechanics sampled exactly (the oracle of the
kernel); :func:`sampled_closed_loop` is the loop as the kernel integrates it (its substeps and
the actuator delay), whose poles :func:`check_stability` inspects when an
:class:`~fricbench.axis.Axis` is built.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import control
import numpy as np

from fricbench.axis.sections import ControllerParams, Effects, MechanicsParams

if TYPE_CHECKING:
    from fricbench.axis.params import Axis

__all__ = [
    "STABILITY_MARGIN",
    "check_stability",
    "closed_loop",
    "closed_loop_tf_continuous",
    "controller",
    "plant",
    "sampled_closed_loop",
    "sampled_plant",
    "spectral_radius",
]

STABILITY_MARGIN = 1.0e-6
"""Tolerance on the unit circle: a loop is refused when a pole has ``|z| > 1 + margin``.

Poles exactly on the circle are allowed (a controller switched off, ``kp = kv = 0``, or
``ti = 0``, which leaves an inert integrator state, puts poles at ``z = 1``); the margin covers
the rounding of eigenvalues there (a double pole at ``z = 1`` is found to about 1e-8).
"""


def plant(axis: Axis, discrete: bool = True) -> control.StateSpace:
    """Mechanics ``M dv/dt = F + d - B v``; inputs ``F`` (motor) and ``d`` (disturbance), N.

    States ``[x, v]``, output ``x``. Discretised with a zero-order hold at ``ts`` when
    ``discrete`` (the kernel holds the force constant over each sample).
    """
    m, b = axis.mechanics.mass, axis.mechanics.damping
    a = np.array([[0.0, 1.0], [0.0, -b / m]])
    bm = np.array([[0.0, 0.0], [1.0 / m, 1.0 / m]])
    sys = control.ss(a, bm, [[1.0, 0.0]], [[0.0, 0.0]], inputs=["F", "d"], outputs=["x"],
                     states=["x", "v"], name="plant")
    if discrete:
        sys = control.c2d(sys, axis.controller.ts, "zoh", name="plant")
    return sys


def sampled_plant(axis: Axis) -> control.StateSpace:
    """The mechanics as the kernel advances them over one sample, friction and effects off
    (but the compliant coupling, when on: states ``d, dv`` after ``x, v``, output the fed-back
    side).

    ``n_substeps`` substeps of ``h = ts / n_substeps`` with the force held, each
    ``v+ = (M v + h F) / (M + h B)`` (implicit in the damping) and ``x+ = x + h (v + v+) / 2``
    (:func:`fricbench.axis.plant.advance`), after a pure delay of ``delay_samples`` samples on
    the command. Inputs ``F`` (commanded motor force) and ``d`` (disturbance, not delayed), N;
    states ``x, v`` and the commands in transit; output ``x``.
    """
    return _sampled_plant(axis.controller, axis.mechanics, axis.effects.delay_samples,
                          _compliance(axis.effects))


Compliance = tuple[float, float, float, bool, bool, float]
"""``(load fraction, resonance Hz, damping ratio, feedback on the table, friction and damping
on the load, the damping's share on the motor then)`` of a compliant axis."""

RIGID: Compliance = (0.0, 50.0, 0.05, False, False, 0.0)


def _compliance(e: Effects) -> Compliance:
    if e.compliance_load_fraction <= 0.0:
        return RIGID
    return (e.compliance_load_fraction, e.compliance_frequency, e.compliance_damping,
            e.measurement == "table", e.compliance_friction == "load",
            e.compliance_damping_motor_share)


def _sampled_plant(c: ControllerParams, m: MechanicsParams, delay: int,
                   comp: Compliance = RIGID) -> control.StateSpace:
    h = c.ts / c.n_substeps
    ratio, f_r, zeta, table, on_load, b_motor_share = comp
    n_mech = 4 if ratio > 0.0 else 2
    a_sub = np.zeros((n_mech, n_mech))
    b_sub = np.zeros(n_mech)
    if ratio > 0.0 and on_load:
        # friction off and B on the load: the exact map of the held actuator force alone
        # (fricbench.axis.plant.compliance_load_constants), on [x, v, d, d']
        from fricbench.axis.plant import compliance_load_constants

        cl = np.array(compliance_load_constants(m.mass, ratio, f_r, zeta, h, m.damping,
                                                b_motor_share))
        phi, gam, psi, lam = cl[:9].reshape(3, 3), cl[9:12], cl[12:15], cl[15]
        a_sub[0] = np.concatenate([[1.0], psi])
        b_sub[0] = lam
        for j in range(3):
            a_sub[j + 1] = np.concatenate([[0.0], phi[j]])
            b_sub[j + 1] = gam[j]
    elif ratio > 0.0:
        # the substep of fricbench.axis.plant.advance with friction off, on [x, v, d, dv]:
        # v_lin = Phi_v s; v+ = v_lin + h F / m_eff; g = m_eff (v+ - v_lin) / h;
        # x+ = x + Psi s + Lambda g; (d, d')+ = Phi_d s + Gamma_d g   (s = [v, d, d'])
        from fricbench.axis.plant import compliance_constants

        cc = np.array(compliance_constants(m.mass, ratio, f_r, zeta, h, m.damping))
        phi, gam, psi, lam = cc[:9].reshape(3, 3), cc[9:12], cc[12:15], cc[15]
        m_eff = h / gam[0]
        den = m_eff  # B is inside the exact map
        v_row = np.concatenate([[0.0], m_eff / den * phi[0]])     # on [x, v, d, d']
        v_in = h / den
        g_row = m_eff / h * (v_row - np.concatenate([[0.0], phi[0]]))
        g_in = m_eff / h * v_in
        a_sub[0] = np.concatenate([[1.0], psi]) + lam * g_row
        b_sub[0] = lam * g_in
        a_sub[1], b_sub[1] = v_row, v_in
        for j in (1, 2):
            a_sub[j + 1] = np.concatenate([[0.0], phi[j]]) + gam[j] * g_row
            b_sub[j + 1] = gam[j] * g_in
    else:
        # one substep: v+ = g v + b F, x+ = x + h/2 (1 + g) v + h/2 b F
        gv = m.mass / (m.mass + h * m.damping)
        b = h / (m.mass + h * m.damping)
        a_sub[:] = [[1.0, 0.5 * h * (1.0 + gv)], [0.0, gv]]
        b_sub[:] = [0.5 * h * b, b]
    a_mech, b_mech = np.eye(n_mech), np.zeros(n_mech)
    for _ in range(c.n_substeps):
        a_mech, b_mech = a_sub @ a_mech, a_sub @ b_mech + b_sub
    n = n_mech + delay
    a, bm = np.zeros((n, n)), np.zeros((n, 2))
    a[:n_mech, :n_mech] = a_mech
    bm[:n_mech, 1] = b_mech
    if delay:
        # states n_mech.. hold F[k-1] .. F[k-delay]; the mechanics get F[k-delay]
        a[:n_mech, n - 1] = b_mech
        a[n_mech:, n_mech:] = np.eye(delay, k=-1)
        bm[n_mech, 0] = 1.0
    else:
        bm[:n_mech, 0] = b_mech
    cm = np.zeros((1, n))
    cm[0, 0] = 1.0
    if ratio > 0.0 and table:
        # a linear scale on the table reads x_M + d
        cm[0, 2] = 1.0
    states = (["x", "v"] + (["d", "dv"] if ratio > 0.0 else [])
              + [f"F[k-{i}]" for i in range(1, delay + 1)])
    return control.ss(a, bm, cm, np.zeros((1, 2)), c.ts, inputs=["F", "d"], outputs=["x"],
                      states=states, name="plant")


def controller(axis: Axis) -> control.StateSpace:
    """The sampled cascade controller; inputs ``x_ref, v_ref, a_ref, u, x``, output ``F`` (N).

    ``e_v = kp (x_ref - x) + kvff v_ref - (x - x_prev)/ts``;
    ``F = kt kv (e_v + I) + kaff M a_ref + u``; ``I+ = I + ts/ti e_v``; states ``[x_prev, I]``.
    """
    return _controller(axis.controller, axis.mechanics)


def _controller(c: ControllerParams, m: MechanicsParams) -> control.StateSpace:
    if c.law == "linear":
        return _law_controller(c)
    ts, kp, kvff = c.ts, c.kp, c.kvff
    gain = c.kt * c.kv
    ki = ts / c.ti if c.ti > 0 else 0.0
    # e_v = kp x_ref + kvff v_ref - (kp + 1/ts) x + x_prev / ts
    ev_in = np.array([kp, kvff, 0.0, 0.0, -(kp + 1.0 / ts)])
    ev_state = np.array([1.0 / ts, 0.0])
    a = np.array([[0.0, 0.0], ev_state * ki + np.array([0.0, 1.0])])
    b = np.vstack([[0.0, 0.0, 0.0, 0.0, 1.0], ki * ev_in])
    cm = gain * (ev_state + np.array([0.0, 1.0]))
    d = gain * ev_in + np.array([0.0, 0.0, c.kaff * m.mass, 1.0, 0.0])
    return control.ss(a, b, cm[None, :], d[None, :], ts,
                      inputs=["x_ref", "v_ref", "a_ref", "u", "x"], outputs=["F"],
                      states=["x_prev", "I"], name="controller")


def _law_controller(c: ControllerParams) -> control.StateSpace:
    """The identified linear law (``law="linear"``) as the controller block of
    :func:`controller`: ``F = kt u_law + u`` with ``u_law = sum_i a_i u_law[k-i] + k_x x_ref
    + k_v v_ref + k_a a_ref + sum_m g_m x_ref[k-m] + sum_j c_j x[k-j]``; states
    ``x[k-1] .. x[k-nc+1]``, ``u[k-1] .. u[k-na]``, then ``x_ref[k-1] .. x_ref[k-nr]``."""
    a, cpos, kref, g_hist = (np.asarray(v, dtype=float) for v in
                             (c.law_recursion, c.law_position, c.law_reference,
                              c.law_reference_history))
    ny, nu, nr = cpos.shape[0] - 1, a.shape[0], g_hist.shape[0]
    n = max(ny + nu + nr, 1)  # a static law keeps one inert state (python-control wants one)
    # output row: u_law = h' s + g' [x_ref, v_ref, a_ref, u, x]
    h = np.zeros(n)
    h[:ny] = cpos[1:]
    h[ny:ny + nu] = a
    h[ny + nu:ny + nu + nr] = g_hist
    g = np.array([kref[0], kref[1], kref[2], 0.0, cpos[0]])
    am, bm = np.zeros((n, n)), np.zeros((n, 5))
    if ny:
        bm[0, 4] = 1.0  # x[k-1]+ = x[k]
        am[1:ny, 0:ny - 1] = np.eye(ny - 1)
    if nu:
        am[ny, :] = h  # u[k-1]+ = u_law[k]
        bm[ny, :] = g
        am[ny + 1:ny + nu, ny:ny + nu - 1] = np.eye(nu - 1)
    if nr:
        r0 = ny + nu
        bm[r0, 0] = 1.0  # x_ref[k-1]+ = x_ref[k]
        am[r0 + 1:r0 + nr, r0:r0 + nr - 1] = np.eye(nr - 1)
    states = ([f"x[k-{j}]" for j in range(1, ny + 1)] + [f"u[k-{i}]" for i in range(1, nu + 1)]
              + [f"x_ref[k-{m}]" for m in range(1, nr + 1)])
    d = c.kt * g + np.array([0.0, 0.0, 0.0, 1.0, 0.0])
    return control.ss(am, bm, c.kt * h[None, :], d[None, :], c.ts,
                      inputs=["x_ref", "v_ref", "a_ref", "u", "x"], outputs=["F"],
                      states=states or ["inert"], name="controller")


def closed_loop(axis: Axis) -> control.StateSpace:
    """Discrete closed loop at ``ts``: inputs ``x_ref, v_ref, a_ref, u, d``; output ``x``.

    This is exactly the loop the kernel simulates with friction and effects off (and no delay,
    saturation or sensor effects); ``u`` is the compensation force at the controller output and
    ``d`` a force disturbance at the plant (friction enters as ``d = -F_f``).
    """
    if axis.effects.delay_samples:
        raise ValueError("closed_loop: delay_samples must be 0 for the linear export")
    return control.interconnect(
        [plant(axis, True), controller(axis)],
        inputs=["x_ref", "v_ref", "a_ref", "u", "d"], outputs=["x"], name="axis")


def sampled_closed_loop(axis: Axis) -> control.StateSpace:
    """The loop the kernel runs with friction and effects off, at ``ts``: :func:`sampled_plant`
    (substeps and actuator delay) closed by :func:`controller`. Inputs and output as in
    :func:`closed_loop` (current saturation, sensor effects and friction left out)."""
    return _sampled_loop(axis.controller, axis.mechanics, axis.effects.delay_samples,
                         _compliance(axis.effects))


def _sampled_loop(c: ControllerParams, m: MechanicsParams, delay: int,
                  comp: Compliance = RIGID) -> control.StateSpace:
    return control.interconnect(
        [_sampled_plant(c, m, delay, comp), _controller(c, m)],
        inputs=["x_ref", "v_ref", "a_ref", "u", "d"], outputs=["x"], name="axis")


@lru_cache(maxsize=512)
def _radius(c: ControllerParams, m: MechanicsParams, delay: int,
            comp: Compliance = RIGID) -> float:
    # keyed by the frozen parameter sets: friction (redrawn per episode) is not part of the key
    return float(np.max(np.abs(_sampled_loop(c, m, delay, comp).poles())))


def spectral_radius(axis: Axis) -> float:
    """Largest pole magnitude ``|z|`` of :func:`sampled_closed_loop` (below 1: stable)."""
    return _radius(axis.controller, axis.mechanics, axis.effects.delay_samples,
                   _compliance(axis.effects))


def check_stability(axis: Axis) -> None:
    """Raise ``ValueError`` when the sampled linear loop of ``axis`` is unstable.

    The poles of :func:`sampled_closed_loop` must satisfy ``|z| <= 1 + STABILITY_MARGIN``.
    Current saturation would otherwise hold an unstable loop bounded and an episode would run
    silently with a limit cycle. The message names the parameters most likely responsible:
    those whose default alone makes the loop stable (else every loop parameter changed from
    its default), with the values of the others and the two rules of thumb.
    """
    c, m, delay = axis.controller, axis.mechanics, axis.effects.delay_samples
    comp = _compliance(axis.effects)
    rho = _radius(c, m, delay, comp)
    if rho <= 1.0 + STABILITY_MARGIN:
        return
    if c.law == "linear":
        raise ValueError(f"controller.law_position={list(c.law_position)!r} with "
                         f"law_recursion={list(c.law_recursion)!r}, kt={c.kt:g} N/A, "
                         f"mechanics.mass={m.mass:g} kg, damping={m.damping:g} N s/m: the "
                         f"sampled closed loop of the linear law is unstable (pole |z|="
                         f"{rho:.4g} at ts={c.ts:g} s, {delay} samples of delay); expected "
                         "every pole |z| <= 1")
    if comp != RIGID and _radius(c, m, delay) <= 1.0 + STABILITY_MARGIN:
        side = "the table (measurement='table')" if comp[3] else "the motor"
        raise ValueError(
            f"effects.compliance_load_fraction={comp[0]:g} with compliance_frequency="
            f"{comp[1]:g} Hz, compliance_damping={comp[2]:g} and feedback from {side}: the "
            f"sampled closed loop is unstable (pole |z|={rho:.4g}) although the rigid axis is "
            "stable; expected a stiffer or better damped coupling, a smaller load fraction, "
            "feedback from the motor, or lower loop gains")
    raise ValueError(_unstable_message(c, m, delay, rho))


# the parameters that move the poles: (section, name, unit); the first six are listed by value
_LOOP = (("controller", "kp", "1/s"), ("controller", "kv", "A s/m"), ("controller", "ti", "s"),
         ("controller", "kt", "N/A"), ("mechanics", "mass", "kg"),
         ("mechanics", "damping", "N s/m"), ("controller", "ts", "s"),
         ("controller", "n_substeps", ""), ("effects", "delay_samples", ""))
_DEFAULTS: dict[str, Any] = {"controller": ControllerParams(), "mechanics": MechanicsParams(),
                             "effects": Effects()}


def _unstable_message(c: ControllerParams, m: MechanicsParams, delay: int, rho: float) -> str:
    given: dict[str, Any] = {"controller": c, "mechanics": m,
                             "effects": Effects(delay_samples=delay)}
    units = {name: unit for _, name, unit in _LOOP}

    def value(parts: dict[str, Any], key: tuple[str, str]) -> Any:
        return getattr(parts[key[0]], key[1])

    def show(parts: dict[str, Any], key: tuple[str, str]) -> str:
        return f"{key[1]}={value(parts, key):g}" + (f" {units[key[1]]}" if units[key[1]] else "")

    def radius_at_default(key: tuple[str, str]) -> float:
        parts = dict(given)
        parts[key[0]] = replace(parts[key[0]], **{key[1]: value(_DEFAULTS, key)})
        return _radius(parts["controller"], parts["mechanics"], parts["effects"].delay_samples)

    loop = [(section, name) for section, name, _ in _LOOP]
    changed = [key for key in loop if value(given, key) != value(_DEFAULTS, key)]
    # the parameters whose default alone makes the loop stable are the likely culprits
    fixes = {key: r for key in changed
             if (r := radius_at_default(key)) <= 1.0 + STABILITY_MARGIN}
    blamed = list(fixes) or changed or [("controller", "kv")]
    head = ", ".join(f"{key[0]}.{show(given, key)}" for key in blamed)
    others = ", ".join(show(given, key) for key in loop[:6] if key not in blamed)
    if fixes:
        fix = "; ".join(f"{show(_DEFAULTS, key)} (the default) gives |z|={r:.3g}"
                        for key, r in fixes.items())
    else:
        fix = ("the defaults " + ", ".join(show(_DEFAULTS, key) for key in blamed)
               + " together give a stable loop")
    wv = c.kv * c.kt / m.mass
    return (head + (f" with {others}" if others else "")
            + f": the sampled closed loop is unstable (pole |z|={rho:.4g} at ts={c.ts:g} s, "
            f"{c.n_substeps} substeps, {delay} samples of delay); expected every pole |z| <= 1 "
            f"({fix}; rules of thumb: kv*kt/mass*ts = {wv * c.ts:.3g}, below about 0.6, and "
            f"kp = {c.kp:g} 1/s well below kv*kt/mass = {wv:.3g} rad/s)")


def closed_loop_tf_continuous(axis: Axis) -> control.TransferFunction:
    """Continuous-time approximation ``G(s) = X(s)/X_ref(s)`` (sampling ignored).

    With ``v_ref = s x_ref`` and ``a_ref = s^2 x_ref``, ``K = kt kv``:
    ``G = [K (ti s + 1)(kvff s + kp) + kaff M ti s^3] / [M ti s^3 + (B + K) ti s^2
    + K (1 + ti kp) s + K kp]``; the paper's eq. (22) has the same form without the integral.
    """
    c, m = axis.controller, axis.mechanics
    if c.law == "linear":
        raise ValueError("closed_loop_tf_continuous: the axis runs an identified linear law "
                         "(controller.law='linear'), a discrete law with no continuous form; "
                         "use closed_loop(axis)")
    gain, mass, damp = c.kt * c.kv, m.mass, m.damping
    s = control.tf("s")
    if c.ti > 0:
        num = gain * (c.ti * s + 1) * (c.kvff * s + c.kp) + c.kaff * mass * c.ti * s**3
        den = mass * c.ti * s**3 + (damp + gain) * c.ti * s**2 + gain * (1 + c.ti * c.kp) * s \
            + gain * c.kp
    else:
        num = gain * (c.kvff * s + c.kp) + c.kaff * mass * s**2
        den = mass * s**2 + (damp + gain) * s + gain * c.kp
    return control.minreal(num / den, verbose=False)
