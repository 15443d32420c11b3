"""Linear controller models of the closed loop: a parametric cascade and an identified ARX law.

Both turn into the generic difference equation of :mod:`fricbench.sysid.diagnose.closed_loop`::

    u[k] = sum_i a_i u[k-i] + r[k] + sum_j c_j x[k-j]

* :class:`CascadeController` is the industrial position/velocity cascade: position P with
  velocity and acceleration feedforward, velocity PI on the backward-difference velocity. It is
  the model when the run has no effort: the mass is then normalised to 1 and ``u`` is an
  acceleration (m/s^2). Its parameters are physical and bounded, so that friction cannot be
  traded for a loop without integral action (a known way to mistake friction for backlash).
* :class:`ArxController` is identified by least squares from a measured effort: any linear law
  in the reference (with look-ahead, for feedforward from a planned trajectory), the measured
  position and its own past outputs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.signal import butter, lfilter

from fricbench.sysid.diagnose.leastsq import matvec, solve_ls, sumsq

__all__ = ["CascadeController", "ArxController", "fit_arx_controller", "LoopInputs"]


@dataclass(frozen=True)
class LoopInputs:
    """Sampled reference signals and initial conditions shared by every simulation of a run.

    Attributes
    ----------
    t : ndarray
        Time from the start of the run, s.
    ts : float
        Sample time, s.
    xr, vr, ar : ndarray
        Reference position (m), velocity (m/s), acceleration (m/s^2), central differences.
    x0, v0 : float
        Initial position (m) and velocity (m/s) of the axis.
    u0 : float
        Initial effort (effort unit, or m/s^2 for the cascade).
    n_loop : int
        Loop periods per logged sample: the controller of a simulation runs ``n_loop`` times
        faster than the log (1: at the log's rate). A drive's loop often runs at 1 kHz or
        faster while its log is written at 100 Hz; a discrete loop at the log's rate cannot
        reproduce it (see :attr:`fine`).
    """

    t: np.ndarray
    ts: float
    xr: np.ndarray
    vr: np.ndarray
    ar: np.ndarray
    x0: float
    v0: float
    u0: float = 0.0
    n_loop: int = 1

    def __post_init__(self) -> None:
        if isinstance(self.n_loop, bool) or not isinstance(self.n_loop, (int, np.integer)) \
                or self.n_loop < 1:
            raise ValueError(f"n_loop={self.n_loop!r}: expected an integer >= 1 (loop periods "
                             "per logged sample)")

    @property
    def loop_ts(self) -> float:
        """The controller's period, s."""
        return self.ts / self.n_loop

    @cached_property
    def fine(self) -> LoopInputs:
        """These inputs at the loop's rate (``n_loop`` = 1): the logged reference
        interpolated by a monotone cubic (PCHIP: no overshoot at a step, unlike a spline),
        its velocity and acceleration by central differences as :func:`prepare` computes them
        on a log. Logged sample ``k`` is loop sample ``k n_loop``."""
        if self.n_loop == 1:
            return self
        n = self.t.shape[0]
        t = self.t[0] + np.arange((n - 1) * self.n_loop + 1) * self.loop_ts
        xr = PchipInterpolator(self.t, self.xr)(t)
        vr = np.gradient(xr, self.loop_ts)
        ar = np.gradient(vr, self.loop_ts)
        return LoopInputs(t=t, ts=self.loop_ts, xr=xr, vr=vr, ar=ar, x0=self.x0, v0=self.v0,
                          u0=self.u0)

    @cached_property
    def ar_step(self) -> np.ndarray:
        """``a_r[k] - a_r[k-1]`` (0 at the first sample)."""
        return self.ar - np.concatenate([[self.ar[0]], self.ar[:-1]])

    def history(self, n: int) -> np.ndarray:
        """Positions ``x[-1] .. x[-n]`` before the run (constant-velocity extrapolation)."""
        return self.x0 - self.v0 * self.ts * np.arange(1, n + 1)


def _reference_taps(t: np.ndarray, inp: LoopInputs) -> np.ndarray:
    """``sum_j t_j x_r[k-j]``, the reference before the run at constant velocity."""
    n = inp.t.shape[0]
    lag = t.shape[0] - 1
    back = np.arange(lag, 0, -1)
    xr = np.concatenate([inp.xr[0] - back * inp.vr[0] * inp.ts, inp.xr])
    r = np.zeros(n)
    for j in range(lag + 1):
        # tap j multiplies the sample k - j
        r += t[j] * xr[lag - j: lag - j + n]
    return r


@dataclass(frozen=True)
class PositionalLaw:
    """A law in positional form, ``u[k] = q[k] + I[k]``, for the simulator's clamping
    anti-windup (see :meth:`CascadeController.positional`).

    ``q[k] = sum_i a_i q[k-i] + r[k] + sum_j c_j x[k-j]`` and the integral's increment
    ``g[k] = sum_i a2_i g[k-i] + r2[k] + sum_j c2_j x[k-j]``; ``q_init``, ``g_init`` their
    values before the run (latest first), ``i_init`` the integral at the first sample,
    ``y_init`` the positions before the run.
    """

    a: np.ndarray
    c: np.ndarray
    r: np.ndarray
    q_init: np.ndarray
    a2: np.ndarray
    c2: np.ndarray
    r2: np.ndarray
    g_init: np.ndarray
    i_init: float
    y_init: np.ndarray


@dataclass(frozen=True)
class CascadeController:
    """Position P + feedforward, velocity PI, per unit mass; or a PID position loop.

    ``e_v = kp (x_r - x) + d_f``, with ``d_f`` the velocity error
    ``d = kvff v_r - (x[k] - x[k-1]) / ts`` through an optional first-order filter
    (``d_f[k] = p d_f[k-1] + (1 - p) d[k]``, ``p`` = ``vel_pole``);
    ``u = wv (e_v + I) + kaff a_r``; ``I[k+1] = I[k] + ts (ki e_v[k] + kpi (x_r[k] - x[k]))``.

    With ``kpi = 0`` and no filter this is the industrial P-PI cascade. A PID position loop
    ``u = P e + I_g int(e) + D de_f/dt`` (derivative through a first-order filter of time
    constant ``T_f``, backward Euler, as drives and LinuxCNC's ``pid`` compute it) is the same
    law with ``wv = D``, ``kp = P / D``, ``ki = 0``, ``kpi = I_g / D``, ``kvff = 1`` and
    ``vel_pole = T_f / (T_f + ts)``; the cascade alone reaches only the PIDs with real
    ``kp, ki`` (``P^2 >= 4 D I_g``) and no derivative filter.

    Parameters
    ----------
    wv : float
        Velocity-loop gain over the mass, ``K_v K_t / M`` (a PID's ``D / M``), rad/s.
    kp : float
        Position gain, 1/s.
    ki : float
        Integral rate ``1 / T_i`` of the velocity PI, 1/s (0: no integral action).
    kvff : float
        Velocity feedforward fraction.
    kaff : float
        Acceleration feedforward fraction.
    kpi : float
        Integral rate of the position error, 1/s^2 (a PID's ``I_g / D``; 0 in a cascade).
    vel_pole : float
        Pole of the velocity-error filter, in [0, 1) (0: no filter).
    """

    wv: float
    kp: float
    ki: float = 0.0
    kvff: float = 0.0
    kaff: float = 0.0
    kpi: float = 0.0
    vel_pole: float = 0.0

    @property
    def is_pid(self) -> bool:
        """Whether the law is of the PID family (a position-error integral)."""
        return self.kpi > 0.0

    def arx(self, inp: LoopInputs) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                              np.ndarray]:
        """Difference-equation form: ``(a, c, r, u_init, y_init)`` for the simulator."""
        if self.kpi != 0.0 or self.vel_pole != 0.0:
            return self._arx_general(inp)
        ts = inp.ts
        alpha = 1.0 - ts * self.ki
        ref_e = self.kp * inp.xr
        ref_e += self.kvff * inp.vr
        prev_ref_e = self.kp * (inp.xr[0] - inp.vr[0] * ts) + self.kvff * inp.vr[0]
        # u[k] = u[k-1] + wv (e_v[k] - alpha e_v[k-1]) + kaff (a_r[k] - a_r[k-1]), computed
        # in place (a law per Jacobian row of the loop's gains: fewer K-sample temporaries),
        # each element by the same operations as the expression
        r = np.empty_like(ref_e)
        r[0] = ref_e[0] - alpha * prev_ref_e
        np.subtract(ref_e[1:], alpha * ref_e[:-1], out=r[1:])
        r *= self.wv
        r += self.kaff * inp.ar_step
        g = self.kp + 1.0 / ts
        c = self.wv * np.array([-g, 1.0 / ts + alpha * g, -alpha / ts])
        a = np.array([1.0])
        y_init = inp.history(3)
        e_prev = prev_ref_e - self.kp * y_init[0] - (y_init[0] - y_init[1]) / ts
        u_init = np.array([self.wv * e_prev + inp.u0])
        return a, c, r, u_init, y_init

    def difference_form(self, ts: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The general law as ``u[k] = sum_i a_i u[k-i] + sum_j (c_j x[k-j] + t_j x_r[k-j])``.

        With ``F = 1 - p z^-1`` (the filter) and ``A = 1 - (1 - ts ki) z^-1`` (the PI), the law
        times ``(1 - z^-1) F`` reads
        ``U (1 - z^-1) F = wv [(kp F A + ts kpi z^-1 F) E + (1 - p) A D]
        + kaff (1 - z^-1) F A_r``
        with ``E = X_r - X``, ``D = (kvff (1 - z^-1) X_r - (1 - z^-1) X) / ts`` and the reference
        acceleration ``A_r = (1 - z^-1)^2 X_r / ts^2``: the reference's velocity and
        acceleration as backward differences of its position, as a drive computes them, so
        that the law is a filter of the reference position alone (an env's linear law holds
        it exactly). Returns ``a`` (2), ``c`` (3) and ``t`` (5 taps).
        """
        p = self.vel_pole
        filt = np.array([1.0, -p])
        pi = np.array([1.0, -(1.0 - ts * self.ki)])
        diff = np.array([1.0, -1.0])
        on_e = self.wv * (self.kp * np.convolve(filt, pi)
                          + ts * self.kpi * np.concatenate([[0.0], filt]))
        on_d = np.convolve(self.wv * (1.0 - p) * pi, diff) / ts
        c = -(on_e + on_d)
        t = np.zeros(5)
        t[:3] += on_e + self.kvff * on_d
        # the feedforward of A_r is not integrated: (1 - z^-1) F (1 - z^-1)^2 / ts^2
        t += self.kaff * np.convolve(np.convolve(diff, np.convolve(diff, diff)), filt) / (ts * ts)
        return np.array([1.0 + p, -p]), c, t

    def _arx_general(self, inp: LoopInputs) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                      np.ndarray, np.ndarray]:
        """:meth:`arx` with the position integral and the velocity filter
        (:meth:`difference_form`)."""
        ts = inp.ts
        a, c, t = self.difference_form(ts)
        r = _reference_taps(t, inp)
        y_init = inp.history(3)
        # the two efforts before the run, at constant velocity (the filter settled, no
        # reference acceleration): the integral reaches u0 at the first sample, so one and two
        # of its updates less before

        def errors(j: int) -> tuple[float, float]:
            e = inp.xr[0] - j * inp.vr[0] * ts - y_init[j - 1]
            return e, (self.kp * e + self.kvff * inp.vr[0] - (y_init[j - 1] - y_init[j]) / ts)

        (e1, ev1), (e2, ev2) = errors(1), errors(2)
        step1 = ts * (self.ki * ev1 + self.kpi * e1)
        step2 = ts * (self.ki * ev2 + self.kpi * e2)
        u_init = np.array([self.wv * (ev1 - step1) + inp.u0,
                           self.wv * (ev2 - step1 - step2) + inp.u0])
        return a, c, r, u_init, y_init

    def positional(self, inp: LoopInputs) -> PositionalLaw:
        """The law in positional form with its integral as a state, for a drive that clips.

        ``u[k] = q[k] + I[k]``, the proportional part ``q F = wv (kp F E + (1 - p) D) +
        kaff F A_r`` and the integral's increment ``g F = wv ts ((ki kp + kpi) F E +
        ki (1 - p) D)`` (``I[k+1] = I[k] + g[k]``), both with the filter ``F = 1 - p z^-1``
        and the signals of :meth:`difference_form`, whose law this is as long as nothing
        clips. When the command clips, the simulator holds the integral while its increment
        pushes further into the limit (clamping anti-windup, as drives and LinuxCNC's ``pid``
        do): :meth:`arx`'s velocity form instead restarts from the limit, which a positional
        controller does not.
        """
        ts, p = inp.ts, self.vel_pole
        filt = np.array([1.0, -p])
        diff = np.array([1.0, -1.0])
        gi = self.ki * self.kp + self.kpi
        # proportional part: taps on x (c) and on x_r (t), recursion a = [p]
        c = -self.wv * (self.kp * filt + (1.0 - p) * diff / ts)
        t = np.zeros(4)
        t[:2] += self.wv * (self.kp * filt + (1.0 - p) * self.kvff * diff / ts)
        t += self.kaff * np.convolve(np.convolve(diff, diff), filt) / (ts * ts)
        # the integral's increment
        c2 = -self.wv * (ts * gi * filt + self.ki * (1.0 - p) * diff)
        t2 = self.wv * (ts * gi * filt + self.ki * (1.0 - p) * self.kvff * diff)
        r, y_init = _reference_taps(t, inp), inp.history(3)
        r2 = _reference_taps(t2, inp)
        # the state before the run at constant velocity, the filter settled, no acceleration
        e1 = inp.xr[0] - inp.vr[0] * ts - y_init[0]
        ev1 = self.kp * e1 + self.kvff * inp.vr[0] - (y_init[0] - y_init[1]) / ts
        q1 = self.wv * ev1
        g1 = self.wv * ts * (self.ki * ev1 + self.kpi * e1)
        e0 = inp.xr[0] - inp.x0
        q0 = self.wv * (self.kp * e0 + self.kvff * inp.vr[0] - (inp.x0 - y_init[0]) / ts)
        return PositionalLaw(a=np.array([p]), c=c, r=r, q_init=np.array([q1]),
                             a2=np.array([p]), c2=c2, r2=r2, g_init=np.array([g1]),
                             i_init=inp.u0 - q0, y_init=y_init)

    def to_dict(self) -> dict[str, float]:
        """JSON-ready parameters with units in the keys."""
        out = {"wv_rad_s": self.wv, "kp_1_s": self.kp, "ki_1_s": self.ki,
               "kvff": self.kvff, "kaff": self.kaff}
        if self.is_pid or self.vel_pole != 0.0:
            out.update({"kpi_1_s2": self.kpi, "vel_pole": self.vel_pole})
        return out

    def pid_gains(self, ts: float) -> dict[str, float]:
        """The PID position loop this law is (per unit mass), when ``ki`` is 0.

        Returns ``P`` (1/s^2), ``I`` (1/s^3), ``D`` (1/s) and the derivative filter's time
        constant ``T_f`` (s) of ``u = P e + I int(e) + D de_f/dt``.
        """
        p = self.vel_pole
        return {"p_1_s2": self.wv * self.kp, "i_1_s3": self.wv * self.kpi, "d_1_s": self.wv,
                "tf_s": ts * p / (1.0 - p) if p < 1.0 else math.inf}

    def with_values(self, **changes: float) -> CascadeController:
        """A copy with some parameters changed."""
        return replace(self, **changes)


@dataclass(frozen=True)
class ArxController:
    """Identified linear control law ``u[k] = sum a_i u[k-i] + sum b_j x_r[k-j] + sum c_j x[k-j]``.

    Parameters
    ----------
    a : ndarray
        Coefficients of ``u[k-1] .. u[k-na]``.
    b : ndarray
        Coefficients of ``x_r[k+lead] .. x_r[k-lag]`` (``lead`` look-ahead samples first).
    c : ndarray
        Coefficients of ``x[k] .. x[k-nc+1]``.
    lead : int
        Look-ahead of the reference, samples.
    relerr_pct : float
        Fit error of the law on its data, ``100 ||u - u_hat|| / ||u||`` (one-step prediction
        from the logged signals, unfiltered).
    prefilter_hz : float or None
        Cut-off of the low-pass prefilter the law was fitted through (None: none).
    clamped : bool
        Whether a drive that clips runs this law in positional form with a clamped integral
        (:meth:`positional`; the law must hold an exact integrator) rather than recursing on
        its clipped output (the velocity form of :meth:`arx`). Which one a drive does is not
        in its unclipped samples: :func:`~fricbench.sysid.diagnose.baselines.fit_law` chooses
        by the simulated position.
    velocity_ki : float
        With ``clamped``: the integral rate ``k_i`` (1/s) of a cascade's velocity PI. Such a
        drive integrates the velocity error ``k_p e + de/dt`` (``e`` the position error), so
        the integral it holds while clipping carries a share ``D k_i e`` of the proportional
        action as well (:meth:`cascade_integral_rates`). 0: a PID's integral of ``e`` alone.
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    lead: int
    relerr_pct: float = field(default=0.0)
    prefilter_hz: float | None = None
    clamped: bool = False
    velocity_ki: float = 0.0

    def __post_init__(self) -> None:
        if self.clamped and not self.has_integrator:
            raise ValueError(f"clamped=True with a={self.a.tolist()!r}: a clamped law needs "
                             "an exact integrator (recursion coefficients summing to 1)")
        if not (math.isfinite(self.velocity_ki) and self.velocity_ki >= 0.0):
            raise ValueError(f"velocity_ki={self.velocity_ki!r}: expected a finite rate >= 0, "
                             "1/s")
        if self.velocity_ki > 0.0 and not self.clamped:
            raise ValueError(f"velocity_ki={self.velocity_ki!r} with clamped=False: the "
                             "integral's rate only matters to a law run clamped")

    @property
    def has_integrator(self) -> bool:
        """Whether the recursion holds an exact integrator (coefficients summing to 1)."""
        return self.a.shape[0] in (1, 2) and abs(float(np.sum(self.a)) - 1.0) <= 1e-9

    def reference_part(self, xr: np.ndarray, vr: np.ndarray, ts: float) -> np.ndarray:
        """``sum_j b_j x_r[k-j]`` with the reference extended at constant velocity."""
        nb = self.b.shape[0]
        lag = nb - 1 - self.lead
        n = xr.shape[0]
        pre = xr[0] - vr[0] * ts * np.arange(lag, 0, -1)
        post = xr[-1] + vr[-1] * ts * np.arange(1, self.lead + 1)
        ext = np.concatenate([pre, xr, post])
        out = np.zeros(n)
        for j in range(nb):
            # coefficient j multiplies x_r[k + lead - j]
            start = lag + self.lead - j
            out += self.b[j] * ext[start:start + n]
        return out

    def arx(self, inp: LoopInputs) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                              np.ndarray]:
        """Difference-equation form: ``(a, c, r, u_init, y_init)`` for the simulator."""
        r = self.reference_part(inp.xr, inp.vr, inp.ts)
        u_init = np.full(max(self.a.shape[0], 1), inp.u0)[: self.a.shape[0]]
        return self.a, self.c, r, u_init, inp.history(max(self.c.shape[0], 1))

    def _integral_split(self) -> tuple[float, float, np.ndarray, np.ndarray]:
        """``(p, alpha, b_rest, c_rest)``: the law split into an integral and the rest.

        With the recursion ``A(z) = (1 - z^-1)(1 - p z^-1)`` (``p = 0`` for one coefficient),
        each input's taps ``N(z)`` split into ``alpha z^-1 / (1 - z^-1) + N'(z) / (1 - p
        z^-1)`` with ``alpha = N(1) / (1 - p)``; the taps of a servo law sum to 0 over both
        inputs, so ``alpha`` is the reference's and ``-alpha`` the position's.
        """
        if not self.has_integrator:
            raise ValueError(f"a={self.a.tolist()!r}: the positional form needs an exact "
                             "integrator (recursion coefficients summing to 1)")
        p = -float(self.a[1]) if self.a.shape[0] == 2 else 0.0
        alpha = float(np.sum(self.b)) / (1.0 - p)

        def rest(taps: np.ndarray) -> np.ndarray:
            # N' = (N - alpha_N (z^-1 - p z^-2)) / (1 - z^-1) with the taps from the highest
            # power down: a running sum divides by (1 - z^-1); its last value, N(1) - alpha_N
            # (1 - p), is 0
            return np.cumsum(taps)[:-1]

        # reference taps from z^lead down: z^-1 and z^-2 sit at lead + 1 and lead + 2
        bb = np.concatenate([self.b, np.zeros(2)])
        bb[self.lead + 1] -= alpha
        bb[self.lead + 2] += alpha * p
        # position taps from z^0 down, alpha_N = -alpha
        cc = np.concatenate([self.c, np.zeros(max(0, 3 - self.c.shape[0]) + 1)])
        cc[1] += alpha
        cc[2] -= alpha * p
        return p, alpha, rest(bb), rest(cc)

    def pid_terms(self, ts: float) -> tuple[float, float, float, float]:
        """``(I, P, D, kvff)``: the law near zero frequency as a PID with velocity feedforward.

        ``u ~ P e + D (kvff v_r - v) + I int(e)`` (``e = x_r - x``): ``I`` (effort per m s)
        from the integral's share ``alpha = I ts``, ``P`` and ``D`` from the rest of the
        position taps ``N'(z) / (1 - p z^-1)`` expanded in ``w = 1 - z^-1`` (``P`` the value
        at ``w = 0``, ``D / ts`` the slope), ``kvff`` the reference taps' slope over the
        position's. Needs an exact integrator.
        """
        p, alpha, b_rest, c_rest = self._integral_split()

        def value_and_slope(taps: np.ndarray, first_power: int) -> tuple[float, float]:
            # sum_j t_j z^-(j + first_power) / (1 - p z^-1) with z^-1 = 1 - w, to first order
            powers = np.arange(taps.shape[0]) + first_power
            s0, s1 = float(np.sum(taps)), float(np.sum(powers * taps))
            return s0 / (1.0 - p), -(s1 / (1.0 - p) + s0 * p / (1.0 - p) ** 2)

        p_x, d_x = value_and_slope(-c_rest, 0)
        _, d_r = value_and_slope(b_rest, -self.lead)
        kvff = d_r / d_x if d_x != 0.0 else 0.0
        return alpha / ts, p_x, d_x * ts, kvff

    def cascade_integral_rates(self, ts: float) -> tuple[float, ...]:
        """The velocity-PI integral rates ``k_i`` (1/s) of the cascades this law can be.

        A cascade ``u = D (k_p e + de/dt) + D k_i int(k_p e + de/dt)`` is, unclipped, the PID
        of :meth:`pid_terms` with ``P = D (k_p + k_i)`` and ``I = D k_p k_i``: ``k_p`` and
        ``k_i`` are the two roots of ``s^2 - (P / D) s + I / D``, interchangeable, and which
        one the drive integrates with only shows while it clips. Both roots, smaller first;
        none when they are not real and positive (a PID that no cascade is).
        """
        i_gain, p_gain, d_gain, _ = self.pid_terms(ts)
        if not (i_gain > 0.0 and p_gain > 0.0 and d_gain > 0.0):
            return ()
        s, prod = p_gain / d_gain, i_gain / d_gain
        disc = s * s - 4.0 * prod
        if not (math.isfinite(disc) and disc >= 0.0):
            return ()
        root = math.sqrt(disc)
        return (0.5 * (s - root), 0.5 * (s + root))

    def positional(self, inp: LoopInputs) -> PositionalLaw:
        """The law in positional form with its integral as a state, for a drive that clips.

        The integral of :meth:`_integral_split`, ``alpha z^-1 / (1 - z^-1)``, runs as a state
        ``I[k+1] = I[k] + g[k]``; the rest ``q`` recurses on ``p``. A PID integrates the
        position error, ``g[k] = alpha e[k]``. A cascade (``velocity_ki`` > 0) integrates its
        velocity error, so ``g[k] = alpha e[k] + beta (kvff (x_r[k] - x_r[k-1]) - (x[k] -
        x[k-1]))`` with ``beta = D k_i`` (:meth:`pid_terms`), and ``q`` gives that share of the
        proportional action back. Unclipped, either is :meth:`arx`'s law; the run is taken to
        start in the steady state of its first samples.
        """
        p, alpha, b_rest, c_rest = self._integral_split()
        beta, kvff = 0.0, 0.0
        if self.velocity_ki > 0.0:
            _, _, d_gain, kvff = self.pid_terms(inp.ts)
            beta = d_gain * self.velocity_ki
            # the integral's beta z^-1 (1 - p z^-1) / (1 - p z^-1) leaves the rest
            b_rest = b_rest.copy()
            b_rest[self.lead + 1] -= beta * kvff
            b_rest[self.lead + 2] += beta * kvff * p
            c_rest = c_rest.copy()
            c_rest[1] += beta
            c_rest[2] -= beta * p
        q_law = ArxController(a=np.array([p]), b=b_rest, c=c_rest, lead=self.lead)
        r = q_law.reference_part(inp.xr, inp.vr, inp.ts)
        y_init = inp.history(max(c_rest.shape[0], 1))
        xr_prev = np.concatenate(([inp.xr[0] - inp.vr[0] * inp.ts], inp.xr[:-1]))
        r2 = alpha * inp.xr + beta * kvff * (inp.xr - xr_prev)
        c2 = np.array([-(alpha + beta), beta]) if beta != 0.0 else np.array([-alpha])
        q_init, i_init = self._positional_start(inp, q_law, r, r2, c2)
        return PositionalLaw(a=np.array([p]), c=c_rest, r=r, q_init=np.array([q_init]),
                             a2=np.array([0.0]), c2=c2, r2=r2,
                             g_init=np.array([0.0]), i_init=i_init, y_init=y_init)

    def _positional_start(self, inp: LoopInputs, q_law: ArxController, r_q: np.ndarray,
                          r2: np.ndarray, c2: np.ndarray) -> tuple[float, float]:
        """``(q[-1], I[0])`` that make the positional form's first two commands those of the
        velocity form started as :meth:`arx` starts it; both recursions agree from there on
        (they share the second-order recursion and its two latest values). The commands are
        affine in the two states: solved from three evaluations (least squares, as ``q[-1]``
        does not matter without a second root)."""
        n_hist = max(self.c.shape[0], q_law.c.shape[0]) + 1
        hist = inp.history(n_hist)
        y = (inp.x0, inp.x0 + inp.v0 * inp.ts)  # any y[1]: it enters both forms alike

        def pos(k: int, j: int) -> float:
            return float(y[k - j]) if k - j >= 0 else float(hist[j - k - 1])

        r_v = self.reference_part(inp.xr[:2], inp.vr[:2], inp.ts)
        u_hist = [inp.u0] * self.a.shape[0]
        u_v = []
        for k in (0, 1):
            u = r_v[k] + sum(float(cj) * pos(k, j) for j, cj in enumerate(self.c))
            u += sum(float(ai) * u_hist[i] for i, ai in enumerate(self.a))
            u_v.append(u)
            u_hist = [u, *u_hist[:-1]]
        p = float(q_law.a[0])

        def mismatch(q_prev: float, i0: float) -> np.ndarray:
            out = []
            integral = i0
            for k in (0, 1):
                q_prev = p * q_prev + r_q[k] + sum(float(cj) * pos(k, j)
                                                   for j, cj in enumerate(q_law.c))
                out.append(u_v[k] - (q_prev + integral))
                integral += r2[k] + sum(float(cj) * pos(k, j) for j, cj in enumerate(c2))
            return np.array(out)

        d0 = mismatch(0.0, 0.0)
        jac = np.column_stack([mismatch(1.0, 0.0) - d0, mismatch(0.0, 1.0) - d0])
        sol = np.linalg.lstsq(jac, -d0, rcond=None)[0]
        return float(sol[0]), float(sol[1])

    def predict(self, xr: np.ndarray, vr: np.ndarray, x: np.ndarray, u: np.ndarray,
                ts: float) -> np.ndarray:
        """One-step effort prediction from measured ``x`` and past measured ``u``."""
        out = self.reference_part(xr, vr, ts)
        for j in range(self.c.shape[0]):
            out[j:] += self.c[j] * x[: x.shape[0] - j]
            out[:j] += self.c[j] * x[0]
        for i in range(self.a.shape[0]):
            out[i + 1:] += self.a[i] * u[: u.shape[0] - i - 1]
            out[: i + 1] += self.a[i] * u[0]
        return out

    def to_dict(self) -> dict[str, object]:
        """JSON-ready coefficients."""
        out: dict[str, object] = {"a": self.a.tolist(), "b_reference": self.b.tolist(),
                                  "c_position": self.c.tolist(),
                                  "reference_lead_samples": self.lead,
                                  "relerr_pct": self.relerr_pct}
        if self.prefilter_hz is not None:
            out["prefilter_hz"] = self.prefilter_hz
        if self.clamped:
            out["anti_windup"] = "clamped integral (positional form) when the drive clips"
            if self.velocity_ki > 0.0:
                out["velocity_ki_1_s"] = self.velocity_ki
        return out


def _design(xr: np.ndarray, x: np.ndarray, u: np.ndarray, na: int, nc: int, lead: int,
            lag: int) -> tuple[np.ndarray, np.ndarray, slice]:
    """Regressors of the law; positions enter as differences to ``x[k]`` (see below)."""
    n = xr.shape[0]
    k0 = max(na, nc - 1, lag)
    k1 = n - lead
    rows = slice(k0, k1)
    xk = x[k0:k1]
    cols = []
    for i in range(1, na + 1):
        cols.append(u[k0 - i:k1 - i])
    # a servo law acts on position differences (shifting reference and position together
    # changes nothing), so sum(b) + sum(c) = 0: c_0 is implied by the other coefficients
    for j in range(-lead, lag + 1):
        cols.append(xr[k0 - j:k1 - j] - xk)
    for j in range(1, nc):
        cols.append(x[k0 - j:k1 - j] - xk)
    return np.column_stack(cols), u[rows], rows


def _solve_law(mat: np.ndarray, rhs: np.ndarray, na: int, integrator: bool) -> np.ndarray:
    """Least-squares coefficients of :func:`_design`'s regression; with ``integrator`` the
    ``na`` recursion coefficients sum to 1 (the last one eliminated: ``u[k] - u[k-na]`` on
    ``u[k-i] - u[k-na]``)."""
    if not integrator:
        return solve_ls(mat, rhs)
    last = mat[:, na - 1]
    red = np.delete(mat, na - 1, axis=1)
    red[:, :na - 1] -= last[:, None]
    coef = solve_ls(red, rhs - last)
    a_last = 1.0 - float(np.sum(coef[:na - 1]))
    return np.concatenate([coef[:na - 1], [a_last], coef[na - 1:]])


def _lowpass(sig: np.ndarray, ba: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """``sig`` through the filter ``ba``, started at rest at its first value."""
    return np.asarray(lfilter(ba[0], ba[1], sig - sig[0])) + sig[0]


def fit_arx_controller(xr: np.ndarray, vr: np.ndarray, x: np.ndarray, u: np.ndarray,
                       ts: float, folds: np.ndarray, *, lead: int = 2, lag: int = 3,
                       nc: int = 4, exclude: np.ndarray | None = None,
                       prefilter_hz: float | None = None, max_na: int = 2,
                       integrator: bool = False) -> ArxController:
    """Identify the control law from reference, measured position and effort.

    Least squares on the equation error. When the logged position is the very signal the
    controller read, the equation error is the controller's own and the estimate is unbiased.
    When it is not (a semi-closed loop: the drive reads the motor encoder, the log holds the
    table's scale; or a log with its own noise), the logged position's noise sits in the
    regressors and biases the high-gain derivative taps (errors in variables): the law then
    predicts the next effort well and the loop badly. A low-pass ``prefilter_hz`` applied
    alike to every signal keeps the law's equation exact (a linear law commutes with a
    linear filter) while it removes most of that noise, the standard prefiltering of
    closed-loop identification (Ljung, *System Identification*, 2nd ed., sec. 14.4).
    The recursion order (0: a static law such as PD, 1: an integrator or a filtered
    derivative, 2: both) is chosen by the error on held-out folds, preferring the simpler
    law unless the richer one is clearly better.

    Parameters
    ----------
    xr, vr, x, u : ndarray, shape (K,)
        Reference position (m) and velocity (m/s), measured position (m), effort.
    ts : float
        Sample time, s.
    folds : ndarray of int, shape (K,)
        Fold label of each sample (0/1).
    lead, lag : int
        Reference look-ahead and look-back, samples.
    nc : int
        Number of position taps ``x[k] .. x[k-nc+1]``.
    exclude : ndarray of bool, shape (K,), optional
        Samples whose effort is not the law's output (a clipped command): equations that
        hold one of them, as output or as recursion, are left out.
    prefilter_hz : float, optional
        Cut-off of a second-order Butterworth low-pass applied to every signal before the
        fit (None: none). Its start-up and the samples it smears a clipped command over are
        left out.
    max_na : int
        Highest recursion order tried.
    integrator : bool
        Hold an exact integrator: the recursion's coefficients sum to 1 (a root at
        ``z = 1``; orders from 1). A PID's integral is exact, but the free fit lands a hair
        inside the unit circle (the next effort hardly depends on it), and a leaky integral
        cannot hold an axis against its friction: on a stiction-dominated PID loop of the
        second simulator the free law's sum 0.99994 (a leak of about 3 s) left 200 times
        the true law's position error.

    Returns
    -------
    ArxController
    """
    def usable(na: int, mat: np.ndarray, rhs: np.ndarray, rows: slice
               ) -> tuple[np.ndarray, np.ndarray, slice | np.ndarray]:
        if exclude is None or not np.any(exclude):
            return mat, rhs, rows
        k = np.arange(rows.start, rows.stop)
        bad = exclude[k].copy()
        for i in range(1, na + 1):
            bad |= exclude[k - i]
        if np.count_nonzero(~bad) < max(50, 0.2 * k.size):
            return mat, rhs, rows  # hardly anything left: the clipped rows are kept
        return mat[~bad], rhs[~bad], k[~bad]

    xr_raw, x_raw, u_raw = xr, x, u
    skip = 0
    if prefilter_hz is not None:
        if not 0.0 < prefilter_hz < 0.5 / ts:
            raise ValueError(f"prefilter_hz={prefilter_hz!r}: expected a cut-off between 0 and "
                             f"the Nyquist frequency {0.5 / ts:g} Hz")
        ba = butter(2, prefilter_hz, fs=1.0 / ts)
        xr, x, u = _lowpass(xr, ba), _lowpass(x, ba), _lowpass(u, ba)
        # the filter's memory: ~4 time constants of its poles
        skip = int(math.ceil(4.0 / (2.0 * math.pi * prefilter_hz * ts)))
        if exclude is not None and np.any(exclude):
            exclude = np.convolve(exclude.astype(float), np.ones(skip + 1))[: exclude.shape[0]] > 0
        start = np.zeros(xr.shape[0], dtype=bool)
        start[:skip] = True
        exclude = start if exclude is None else (exclude | start)
    if integrator and max_na < 1:
        raise ValueError(f"max_na={max_na!r} with integrator=True: expected an order >= 1")
    best: tuple[float, int] | None = None
    for na in range(1 if integrator else 0, max_na + 1):
        mat, rhs, rows = usable(na, *_design(xr, x, u, na, nc, lead, lag))
        f = folds[rows]
        sse = 0.0
        for k in (0, 1):
            tr, te = f != k, f == k
            coef = _solve_law(mat[tr], rhs[tr], na, integrator)
            sse += sumsq(rhs[te] - matvec(mat[te], coef))
        # a richer law must be clearly better, and cannot be when the simpler one is exact
        # (within 0.01 % rms)
        if best is None or (sse < 0.8 * best[0] and best[0] > 1e-8 * sumsq(rhs)):
            best = (sse, na)
    na = best[1] if best is not None else 0
    mat, rhs, rows = usable(na, *_design(xr, x, u, na, nc, lead, lag))
    coef = _solve_law(mat, rhs, na, integrator)
    a = coef[:na]
    b = coef[na:na + lead + lag + 1]
    c_rest = coef[na + lead + lag + 1:]
    c = np.concatenate([[-(np.sum(b) + np.sum(c_rest))], c_rest])
    law = ArxController(a=a, b=b, c=c, lead=lead, prefilter_hz=prefilter_hz)
    # the error that counts is the law's on the logged (unfiltered) signals
    err = u_raw - law.predict(xr_raw, vr, x_raw, u_raw, ts)
    keep = np.ones(err.shape[0], dtype=bool)
    keep[: max(skip, lag + nc)] = False
    keep[err.shape[0] - lead:] = False
    if exclude is not None:
        keep &= ~exclude
    if np.count_nonzero(keep) < 50:
        keep[:] = True
    rel = float(100.0 * np.sqrt(sumsq(err[keep]) / max(sumsq(u_raw[keep]), 1e-300)))
    return replace(law, relerr_pct=rel)
