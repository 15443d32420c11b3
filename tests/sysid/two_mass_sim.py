"""An independent two-mass axis simulator for the compliance tests (not the fricbench plant).

The linear two-mass mechanics (motor and load on a spring and a damper, viscous damping on
the motor) discretised exactly with a zero-order hold (``scipy.linalg.expm``), driven open loop
by an effort or closed by a discrete cascade (position P, velocity PI on a backward
difference) on the motor encoder. Parameters are drawn from a seed within the ranges of
ball-screw feed axes sampled at 1 kHz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm


@dataclass(frozen=True)
class TwoMass:
    """A two-mass axis: total mass (kg), load share, resonance (Hz), damping ratio, motor-side
    viscous damping (N s/m)."""

    mass: float
    ratio: float
    f_r: float
    zeta: float
    damping: float

    @property
    def f_a(self) -> float:
        """Anti-resonance seen from the motor, Hz."""
        return self.f_r * np.sqrt(1.0 - self.ratio)

    def matrices(self, ts: float) -> tuple[np.ndarray, np.ndarray]:
        """ZOH discretisation of ``[x_M, v_M, x_L, v_L]`` with the motor force as input."""
        m_l = self.ratio * self.mass
        m_m = self.mass - m_l
        mu = m_m * m_l / self.mass
        w = 2.0 * np.pi * self.f_r
        k, c = mu * w * w, 2.0 * self.zeta * mu * w
        a = np.array([[0.0, 1.0, 0.0, 0.0],
                      [-k / m_m, -(c + self.damping) / m_m, k / m_m, c / m_m],
                      [0.0, 0.0, 0.0, 1.0],
                      [k / m_l, c / m_l, -k / m_l, -c / m_l]])
        b = np.array([0.0, 1.0 / m_m, 0.0, 0.0])
        big = np.zeros((5, 5))
        big[:4, :4], big[:4, 4] = a * ts, b * ts
        e = expm(big)
        return e[:4, :4], e[:4, 4]


def draw(rng: np.random.Generator, f_lo: float = 10.0, f_hi: float = 80.0) -> TwoMass:
    """A ball-screw axis with a compliant coupling: resonance in ``[f_lo, f_hi]`` Hz."""
    mass = float(np.exp(rng.uniform(np.log(20.0), np.log(400.0))))
    return TwoMass(mass=mass, ratio=float(rng.uniform(0.2, 0.6)),
                   f_r=float(rng.uniform(f_lo, f_hi)), zeta=float(rng.uniform(0.01, 0.08)),
                   damping=float(rng.uniform(3.0, 8.0)) * mass)


def moves(rng: np.random.Generator, n: int, ts: float, accel: float = 2.0,
          jerk_time: float = 0.004) -> np.ndarray:
    """A reference of back-and-forth moves: bang-bang accelerations of random lengths with a
    jerk-limited rise (``jerk_time``), dwells between; returns positions, m."""
    a = np.zeros(n)
    k = int(0.1 / ts)
    sign = 1.0
    while k < n - 1:
        t_acc = int(rng.uniform(0.03, 0.12) / ts)
        t_cruise = int(rng.uniform(0.0, 0.15) / ts)
        lvl = sign * accel * rng.uniform(0.5, 1.0)
        a[k:k + t_acc] = lvl
        a[k + t_acc + t_cruise:k + 2 * t_acc + t_cruise] = -lvl
        k += 2 * t_acc + t_cruise + int(rng.uniform(0.05, 0.25) / ts)
        sign = -sign if rng.uniform() < 0.7 else sign
    win = max(int(round(jerk_time / ts)), 1)
    a = np.convolve(a, np.ones(win) / win, mode="same")
    v = np.cumsum(a) * ts
    return np.cumsum(v) * ts


def closed_loop(axis: TwoMass, x_ref: np.ndarray, ts: float, rng: np.random.Generator, *,
                noise: float = 2e-8, bandwidth: float = 250.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cascade on the motor encoder: logged motor position, load position and force."""
    ad, bd = axis.matrices(ts)
    wv = bandwidth
    kv, kp, ki = wv * axis.mass, wv / 4.0, wv / 8.0  # velocity gain N s/m, 1/s, 1/s
    n = x_ref.shape[0]
    vr = np.gradient(x_ref, ts)
    s = np.zeros(4)
    s[0] = s[2] = x_ref[0]
    x_m, x_l, u = np.empty(n), np.empty(n), np.empty(n)
    y_prev = x_ref[0]
    integ = 0.0
    for k in range(n):
        y = s[0] + noise * rng.standard_normal()
        x_m[k], x_l[k] = y, s[2] + noise * rng.standard_normal()
        # v_cmd = kp (x_r - y) + v_r ; F = kv (e_v + I)
        e_v = kp * (x_ref[k] - y) + vr[k] - (y - y_prev) / ts
        integ += ki * ts * e_v
        u[k] = kv * (e_v + integ)
        y_prev = y
        s = ad @ s + bd * u[k]
    return x_m, x_l, u


def open_loop(axis: TwoMass, n: int, ts: float, rng: np.random.Generator, *,
              noise: float = 2e-8, f_max: float = 120.0, repeats: int = 2
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An identification experiment: ``repeats`` times, from rest, a tapered random-phase
    multisine force (0.5 .. ``f_max`` Hz) and a rest while the axis stops; returns the motor
    position, the load position and the force."""
    per = n // repeats
    t = np.arange(per) * ts
    burst = (t >= 0.1 * per * ts) & (t < 0.7 * per * ts)
    tb = t[burst] - t[burst][0]
    f = np.arange(0.5, f_max, 0.5)
    u = np.zeros(n)
    for j in range(repeats):
        ph = rng.uniform(0.0, 2.0 * np.pi, f.size)
        ms = np.sin(2.0 * np.pi * f[:, None] * tb[None, :] + ph[:, None]).sum(axis=0)
        ms *= np.hanning(tb.size) / np.std(ms)
        seg = np.zeros(per)
        seg[burst] = axis.mass * ms
        u[j * per:(j + 1) * per] = seg
    ad, bd = axis.matrices(ts)
    s = np.zeros(4)
    x_m, x_l = np.empty(n), np.empty(n)
    for k in range(n):
        x_m[k], x_l[k] = (s[0] + noise * rng.standard_normal(),
                          s[2] + noise * rng.standard_normal())
        s = ad @ s + bd * u[k]
    return x_m, x_l, u
