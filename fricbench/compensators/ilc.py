"""``ilc``: iterative learning control over rehearsals of the same reference.

Before the scored run the reference is rehearsed on the machine (``context.rehearse``, each
time with a new noise seed) and a feedforward ``u`` is learned from the measured error
``e = x_ref - x``::

    u_{j+1} = Q( u_j + gamma L e_j )

``ilc`` (:class:`IterativeLearningControl`) learns a *reference offset* ``u`` in m (the
"serial" architecture of CNC ILC: the learned correction is added to the position command,
and its backward-difference rate to the velocity feedforward, as the drive does).
:class:`ForceILC` learns a force at the velocity-loop output instead (the "parallel"
architecture); it is not registered by default because the paper axis's action range (600 N) is
smaller than friction plus the un-fed-forward inertia ``M a`` on fast references, so its
learning saturates (see ``docs/compensators.md``).

* ``L``: a regularised inverse of the nominal path ``P(z)`` from ``u`` to position of the
  linear closed loop (:func:`fricbench.axis.closed_loop`)::

      L(e^{jw}) = conj(P) / (|P|^2 + beta max|P|^2)

  applied non-causally over the whole trial by FFT (zero-padded, so no wrap-around). For the
  offset ``P = G_xref + G_vref (1 - z^-1) / ts`` has unit DC gain; for the force ``P`` has no
  DC gain (the velocity integrator rejects a constant force), which ``beta`` keeps from blowing
  up the inverse.
* ``Q``: zero-phase low-pass (a Butterworth of order ``q_order`` run forwards and backwards,
  ``scipy.signal.filtfilt``) with cutoff ``q_cutoff``: the robustness filter; the error is
  learned up to about that frequency, above it the iteration is left alone.
* ``gamma`` in (0, 1]: learning gain; smaller is slower but smoother under the stick-slip
  nonlinearity of friction.

The learned offset is clipped to the env's action range (``context.task.action_scale``: the
bench gives an offset compensator :attr:`~fricbench.gym.task.TaskConfig.offset_scale`, sized from
the env's own tracking-error scale).

After ``iterations`` rehearsals the input with the smallest *measured* max |e| is kept (the
safeguard an operator uses on a machine; ``keep="last"`` takes the latest update instead).
``history_`` records the convergence per iteration.
"""

from __future__ import annotations

from functools import lru_cache
from typing import ClassVar

import control
import numpy as np

from fricbench._validation import check_choice, check_int, check_positive, check_range
from fricbench.axis import Axis, closed_loop
from fricbench.compensators.base import Compensator, CompensatorError, EpisodeContext
from fricbench.sysid.inverse import inverse_gain, zero_phase_lowpass

__all__ = ["IterativeLearningControl", "ForceILC", "impulse_response"]


@lru_cache(maxsize=16)
def _impulse_cached(axis: Axis, n: int, mode: str) -> np.ndarray:
    sys = closed_loop(axis)
    ts = axis.controller.ts
    u = np.zeros((len(sys.input_labels), n))
    if mode == "force":
        u[sys.input_labels.index("u"), 0] = 1.0
    else:
        # an offset pulse enters the position command and, as its backward-difference rate,
        # the velocity feedforward: v_cmd = kp (x_r + u - x) + kvff (v_r + (u[k] - u[k-1])/ts)
        u[sys.input_labels.index("x_ref"), 0] = 1.0
        u[sys.input_labels.index("v_ref"), :2] = [1.0 / ts, -1.0 / ts]
    resp = control.forced_response(sys, T=np.arange(n) * ts, U=u)
    return np.ravel(resp.outputs)


def impulse_response(axis: Axis, mode: str = "offset", n: int = 3000) -> np.ndarray:
    """Impulse response of the linear closed loop from ``u`` to position.

    Parameters
    ----------
    axis : Axis
        Nominal axis (friction and effects ignored: the linear loop).
    mode : {"offset", "force"}
        ``u`` is a reference offset (response in m/m) or a force at the velocity-loop output
        (m/N).
    n : int
        Samples.
    """
    check_choice("mode", mode, ("offset", "force"))
    check_int("n", n, 16, 1_000_000)
    h = _impulse_cached(axis, n, mode)
    if np.max(np.abs(h[-n // 10:])) > 1e-3 * np.max(np.abs(h)):
        raise ValueError(f"n={n}: the impulse response has not decayed within {n} samples; "
                         "increase model_length")
    return h.copy()


class IterativeLearningControl(Compensator):
    """Model-inverse ILC of a reference offset with a zero-phase Q-filter, learned by
    rehearsing the reference.

    Parameters
    ----------
    iterations : int
        Rehearsals before the scored run.
    gain : float
        Learning gain ``gamma`` in (0, 1].
    q_cutoff : float
        Cutoff of the zero-phase Q low-pass, Hz.
    q_order : int
        Butterworth order of one pass of the Q-filter (the zero-phase filter has twice it).
    beta : float
        Regularisation of the model inverse, relative to ``max |P|^2``.
    keep : {"best", "last"}
        Use the rehearsed input with the smallest measured max |e|, or the last update.
    model_length : int
        Samples of the nominal impulse response used for ``P``.

    Attributes
    ----------
    history_ : list of dict
        Per rehearsal ``j``: ``max_measured_um`` (what the machine sees), ``max_true_um``
        (simulator only, for the docs), ``rms_measured_um``.
    kept_iteration_ : int
        The rehearsal whose input is used in the scored run (``iterations`` for the last
        update with ``keep="last"``).
    """

    id = "ilc"
    action_mode: ClassVar[str] = "offset"
    learns: ClassVar[bool] = False
    category: ClassVar[str] = "trials"

    def __init__(self, *, iterations: int = 30, gain: float = 0.5, q_cutoff: float = 150.0,
                 q_order: int = 2, beta: float = 1e-2, keep: str = "best",
                 model_length: int = 3000) -> None:
        super().__init__()
        check_int("iterations", iterations, 1, 10_000)
        check_range("gain", gain, 1e-6, 1.0)
        check_positive("q_cutoff", q_cutoff, "Hz")
        check_int("q_order", q_order, 1, 8)
        check_positive("beta", beta)
        check_choice("keep", keep, ("best", "last"))
        check_int("model_length", model_length, 16, 1_000_000)
        self.iterations = iterations
        self.gain = gain
        self.q_cutoff = q_cutoff
        self.q_order = q_order
        self.beta = beta
        self.keep = keep
        self.model_length = model_length
        self._u = np.zeros((1, 1))
        self._k = 0

    def _reset(self, context: EpisodeContext, seed: int | None) -> None:
        if context.rehearse is None:
            raise CompensatorError(f"{self.id}: needs context.rehearse (rehearsals of the "
                                   "reference before the scored run) but the runner gave None")
        self._u = self.learn(context, seed)
        self._scale = context.task.action_scale
        self._k = 0

    def learn(self, context: EpisodeContext, seed: int | None) -> np.ndarray:
        """Rehearse ``iterations`` times; return the learned ``u`` (m or N), shape (D, K)."""
        axis, ref, rehearse = context.nominal_axis, context.reference, context.rehearse
        if rehearse is None:
            raise CompensatorError(f"{self.id}: needs context.rehearse to learn")
        ts = axis.controller.ts
        nyquist = 0.5 / ts
        if self.q_cutoff >= nyquist:
            raise ValueError(f"q_cutoff={self.q_cutoff:g} Hz: expected below the Nyquist "
                             f"frequency {nyquist:g} Hz of ts={ts:g} s")
        d, k_total = ref.n_axes, ref.n_samples
        h = impulse_response(axis, self.action_mode, self.model_length)
        n_fft = 1 << int(np.ceil(np.log2(k_total + h.size)))
        # L = gamma conj(P) / (|P|^2 + beta max|P|^2)
        learn = self.gain * inverse_gain(h, n_fft, self.beta)
        limit = context.task.action_scale
        seeds = np.random.SeedSequence(0 if seed is None else int(seed)).generate_state(
            self.iterations)
        u = np.zeros((d, k_total))
        best = (np.inf, u.copy(), 0)
        self.history_: list[dict[str, float]] = []
        for j in range(self.iterations):
            res = rehearse(u[0] if d == 1 else u, int(seeds[j]))
            e = np.atleast_2d(res.measured_error)
            e_true = np.atleast_2d(res.error)
            if not np.all(np.isfinite(e)):
                raise CompensatorError(f"{self.id}: rehearsal {j} returned a non-finite error")
            max_meas = float(np.max(np.abs(e)))
            self.history_.append({"iteration": j, "max_measured_um": 1e6 * max_meas,
                                  "max_true_um": 1e6 * float(np.max(np.abs(e_true))),
                                  "rms_measured_um": 1e6 * float(np.sqrt(np.mean(e**2)))})
            if max_meas < best[0]:
                best = (max_meas, u.copy(), j)
            # u_{j+1} = Q(u_j + gamma L e_j)
            du = np.fft.irfft(learn * np.fft.rfft(e, n_fft, axis=1), n_fft, axis=1)[:, :k_total]
            u = zero_phase_lowpass(u + du, self.q_cutoff, ts, self.q_order)
            u = np.clip(u, -limit, limit)
        if self.keep == "best":
            self.kept_iteration_ = best[2]
            return best[1]
        self.kept_iteration_ = self.iterations
        return u

    def _act(self, observation: np.ndarray) -> np.ndarray:
        k = min(self._k, self._u.shape[1] - 1)
        self._k += 1
        return self._u[:, k] / self._scale

    def _planned(self, n_steps: int) -> np.ndarray:
        idx = np.minimum(self._k + np.arange(n_steps), self._u.shape[1] - 1)
        self._k += n_steps
        return self._u[:, idx] / self._scale


class ForceILC(IterativeLearningControl):
    """The same ILC learning a force at the velocity-loop output (parallel architecture), N.

    Not registered by default (see the module docstring); register it with
    ``compensator_registry.register("ilc-force", "fricbench.compensators.ilc:ForceILC")``.
    """

    id = "ilc-force"
    action_mode: ClassVar[str] = "force"
