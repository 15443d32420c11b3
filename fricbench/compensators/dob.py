"""The model of the Kalman disturbance observer (DOB): ``kalman``'s, the observer bank's, ``ekf``'s.

State ``s = [x, v, d]`` (position m, velocity m/s, disturbance force N) with the nominal mass
``M`` and damping ``B`` of ``context.nominal_axis``::

    dx/dt = v
    dv/dt = (F + d - B v) / M        F: motor force (observation column ``motor_force``)
    dd/dt = w                        w: white noise of spectral density q_d (random walk)

discretised with a zero-order hold at the control period ``ts`` (the drive holds the force
over a sample). The measurement is the encoder position ``z = x + n`` reconstructed from the
observation as ``x = x_ref - e``. Friction enters as ``d = -F_f``, so the compensation force
fed back at the velocity-loop output is ``u = -d_hat``.

Tuning (see ``docs/compensators.md``)
------------------------------------
* ``R``: variance of the position measurement, ``q^2 / 12`` for an encoder step ``q``
  (uniform quantisation error) plus ``noise_std^2``; floored at ``(1 nm)^2``.
* ``Q``: chosen for a wanted observer bandwidth ``omega_o``. With the continuous-equivalent
  measurement density ``R_c = R ts``, the steady-state filter of the chain
  ``d -> 1/(M s^2) -> x`` has its three poles on a Butterworth circle of radius
  ``omega_o = (q_d / (M^2 R_c))^(1/6)``, hence ``q_d = M^2 R ts omega_o^6`` (N^2/s). The
  discrete ``Q`` is the exact Van Loan integral of that density over ``ts``.
  :func:`observer_poles` returns the achieved discrete poles for checking.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from fricbench._validation import check_positive
from fricbench.axis import Axis

__all__ = ["dob_model", "initial_covariance", "observer_poles"]

_R_FLOOR = 1.0e-18  # m^2: (1 nm)^2, keeps the filter well posed for an ideal sensor


def dob_model(axis: Axis, bandwidth: float) -> dict[str, np.ndarray]:
    """Discrete model and noise covariances of the disturbance observer.

    Parameters
    ----------
    axis : Axis
        Nominal axis (mass, damping, sample time, encoder step and noise).
    bandwidth : float
        Wanted observer bandwidth ``omega_o``, rad/s.

    Returns
    -------
    dict
        ``F`` (3x3), ``B`` (3x1), ``H`` (1x3), ``Q`` (3x3), ``R`` (1x1), ``q_d`` (N^2/s).
    """
    check_positive("bandwidth", bandwidth, "rad/s")
    m, b, ts = axis.mechanics.mass, axis.mechanics.damping, axis.controller.ts
    q_step = axis.effects.quantization
    # R = q^2 / 12 + sigma_n^2 (uniform quantisation error plus sensor noise)
    r = max(q_step**2 / 12.0 + axis.effects.noise_std**2, _R_FLOOR)
    # q_d = M^2 R_c omega_o^6 with R_c = R ts: Butterworth poles of radius omega_o
    q_d = m**2 * r * ts * bandwidth**6
    a = np.array([[0.0, 1.0, 0.0], [0.0, -b / m, 1.0 / m], [0.0, 0.0, 0.0]])
    bu = np.array([[0.0], [1.0 / m], [0.0]])
    g = np.array([[0.0], [0.0], [1.0]])
    # ZOH: [Phi Gamma; 0 I] = expm([A B; 0 0] ts)
    big = np.zeros((4, 4))
    big[:3, :3], big[:3, 3:] = a, bu
    e = linalg.expm(big * ts)
    phi, gamma = e[:3, :3], e[:3, 3:]
    # Van Loan: Q = int_0^ts Phi(s) G q_d G' Phi(s)' ds
    vl = np.zeros((6, 6))
    vl[:3, :3], vl[:3, 3:], vl[3:, 3:] = -a, g @ g.T * q_d, a.T
    ev = linalg.expm(vl * ts)
    qd = ev[3:, 3:].T @ ev[:3, 3:]
    qd = 0.5 * (qd + qd.T)
    return {"F": phi, "B": gamma, "H": np.array([[1.0, 0.0, 0.0]]), "Q": qd,
            "R": np.array([[r]]), "q_d": np.array(q_d)}


def initial_covariance(axis: Axis, mdl: dict[str, np.ndarray]) -> np.ndarray:
    """``P_0`` of the observer: certain of position and velocity (at rest on the reference),
    unsure of ``d`` by the nominal breakaway force (``mdl``: :func:`dob_model`'s)."""
    fs = axis.friction.kernel_params()["fs"]
    return np.diag([mdl["R"][0, 0], 1e-8, fs**2 + 1.0])


def observer_poles(axis: Axis, bandwidth: float) -> np.ndarray:
    """Continuous-equivalent poles ``ln(z)/ts`` of the steady-state filter, rad/s.

    ``z`` are the eigenvalues of ``(I - K H) F`` with the steady-state gain ``K``.
    """
    mdl = dob_model(axis, bandwidth)
    f, h, q, r = mdl["F"], mdl["H"], mdl["Q"], mdl["R"]
    # P = F P F' - F P H'(H P H' + R)^-1 H P F' + Q  (prior covariance, DARE)
    p = linalg.solve_discrete_are(f.T, h.T, q, r)
    k = p @ h.T @ np.linalg.inv(h @ p @ h.T + r)
    z = np.linalg.eigvals((np.eye(3) - k @ h) @ f)
    return np.log(z.astype(complex)) / axis.controller.ts
