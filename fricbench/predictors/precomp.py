"""Pre-compensation: turn any fitted predictor into a position feedforward.

The axis is commanded ``x_r' = x_r + e_pred`` instead of ``x_r`` (paper, Sec. 3.3, after its
refs. [3] and [26]), where ``e_pred`` is the tracking error the predictor expects. Iterated,
the offset becomes the fixed point of::

    u_0 = 0
    u_{i+1} = u_i + gain (x_r - predict(x_r + u_i))  # i = 0, gain 1 gives u_1 = e_pred

i.e. the command whose *predicted* response is the nominal reference. One iteration is the
paper's one-shot pre-compensation.

``inverse=True`` (model-inverse pre-compensation) replaces each correction ``c`` by
``Q(L c)``, the stable non-causal inverse of the predictor's own transfer function ``G``
(:mod:`fricbench.sysid.inverse`): the offset that the loop turns into the wanted correction,
instead of assuming ``G = 1``. The loop passes a command change to the position with its own
lag, so shifting the reference by ``e_pred`` alone arrives late and small at the friction
spikes, which last a few loop time constants.

How to apply it on the simulator (the actual error is measured there, never the predicted one)::

    offset = precompensation_offset(predictor, reference, iterations=1)
    res = simulate(axis, reference, u_offset=offset)      # res.error: actual tracking error

``simulate`` adds ``u_offset`` to the position reference and its backward difference over
``ts`` to the velocity feedforward; ``res.x_ref`` stays the nominal reference, so ``res.error``
is measured against the path the user wanted.
"""

from __future__ import annotations

import numpy as np

from fricbench._validation import check_int, check_positive, check_range
from fricbench.predictors.base import Predictor
from fricbench.sysid.inverse import pulse_response, stable_inverse
from fricbench.trajectories.base import Reference

__all__ = ["precompensation_offset", "precompensated_reference"]


def precompensation_offset(predictor: Predictor, reference: Reference, iterations: int = 1, *,
                           gain: float = 1.0, advance: int = 0, inverse: bool = False,
                           beta: float = 1e-2, q_cutoff: float = 100.0) -> np.ndarray:
    """Reference offset that pre-compensates the predicted tracking error, m, shape (K,).

    Parameters
    ----------
    predictor : Predictor
        A fitted predictor (any registered id).
    reference : Reference
        Nominal single-axis reference, sampled at the predictor's ``ts_``.
    iterations : int, optional
        1: one-shot ``x_r + e_pred``; more: fixed-point iterations (module docstring).
    gain : float, optional
        Step of each iteration (``(0, 1]``; below 1 damps an oscillating iteration).
    advance : int, optional
        Samples by which each correction is applied earlier (phase lead, as in lead-ILC):
        the loop needs time to build force, so a correction commanded a few samples ahead
        acts when the error happens. 0 (default) is the paper's ``x_r + e_pred``.
    inverse : bool, optional
        Pass each correction through the regularised stable inverse of the predictor's
        transfer function ``tf_`` (module docstring); needs a predictor with ``tf_``.
    beta : float, optional
        Regularisation of the inverse, relative to ``max |G|^2`` (``inverse=True`` only).
    q_cutoff : float, optional
        Cutoff of the zero-phase low-pass on the inverted correction, Hz (``inverse=True``).

    Returns
    -------
    ndarray
        ``u`` to pass as ``simulate(axis, reference, u_offset=u)``.
    """
    if not isinstance(predictor, Predictor):
        raise TypeError(f"predictor={predictor!r}: expected a fitted Predictor")
    iterations = check_int("iterations", iterations, 1, 1000)
    gain = check_range("gain", gain, 1e-6, 1.0)
    advance = check_int("advance", advance, 0, 1000)
    if not isinstance(reference, Reference):
        raise TypeError(f"reference={type(reference).__name__}: expected a Reference")
    x_r = np.asarray(reference.x, dtype=float)
    h = None
    if inverse:
        g = getattr(predictor, "tf_", None)
        if g is None:
            raise ValueError(f"inverse=True: predictor {type(predictor).__name__} has no "
                             "identified transfer function tf_ to invert; use inverse=False")
        check_positive("beta", beta)
        check_positive("q_cutoff", q_cutoff, "Hz")
        h = pulse_response(g, reference.ts)
    offset = np.zeros_like(x_r)
    for _ in range(iterations):
        commanded = reference if not offset.any() else precompensated_reference(reference, offset)
        # u <- u + gain (x_r - x_pred(x_r + u)), shifted `advance` samples earlier
        step = x_r - predictor.predict(commanded)
        if advance:
            step = np.concatenate([step[advance:], np.full(min(advance, step.shape[0]),
                                                           step[-1])])[: step.shape[0]]
        if h is not None:
            step = stable_inverse(h, step, reference.ts, beta=beta, cutoff=q_cutoff)
        offset = offset + gain * step
    return offset


def precompensated_reference(reference: Reference, offset: np.ndarray) -> Reference:
    """The commanded reference ``x_r + u`` (velocity and acceleration by central differences)."""
    offset = np.asarray(offset, dtype=float)
    if offset.shape != np.shape(reference.x):
        raise ValueError(f"offset has shape {offset.shape}: expected {np.shape(reference.x)}")
    return Reference.from_positions(reference.t, reference.x + offset,
                                    name=f"{reference.name}+precomp", params=reference.params)
