"""The linear part of the axis (friction and effects off) as python-control systems."""

from __future__ import annotations

import control
import numpy as np

from fricbench.axis.params import Axis

__all__ = ["closed_loop", "closed_loop_tf_continuous", "controller", "plant"]


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


def controller(axis: Axis) -> control.StateSpace:
    """The sampled cascade controller; inputs ``x_ref, v_ref, a_ref, u, x``, output ``F`` (N).

    ``e_v = kp (x_ref - x) + kvff v_ref - (x - x_prev)/ts``;
    ``F = kt kv (e_v + I) + kaff M a_ref + u``; ``I+ = I + ts/ti e_v``; states ``[x_prev, I]``.
    """
    c, m = axis.controller, axis.mechanics
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


def closed_loop_tf_continuous(axis: Axis) -> control.TransferFunction:
    """Continuous-time approximation ``G(s) = X(s)/X_ref(s)`` (sampling ignored).

    With ``v_ref = s x_ref`` and ``a_ref = s^2 x_ref``, ``K = kt kv``:
    ``G = [K (ti s + 1)(kvff s + kp) + kaff M ti s^3] / [M ti s^3 + (B + K) ti s^2
    + K (1 + ti kp) s + K kp]``; the paper's eq. (22) has the same form without the integral.
    """
    c, m = axis.controller, axis.mechanics
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
