"""One compiled call per vector-env step: action check, reference look-up, the axis kernel,
observation, reward and truncation for every sub-env.

The physics is the kernel's own per-axis body (:func:`fricbench.axis.kernel.advance_axis_with`,
with the plant constants and gains of each row, or of the one row every sub-env shares) and
the observation is that of :func:`fricbench.gym.task.observe_row` (the reset's and the scalar
env's), its reference features copied from a table scaled once (:func:`reference_features`);
this module only fuses the per-step glue around them, which in numpy cost as much as the
physics at 4096 envs (a dozen passes over the batch and their temporaries).

The step is compiled without numba's reference counting (``_nrt=False``: it allocates nothing).
With it, every sub-env paid an atomic increment and decrement for each array handed to the
inlined kernel body and observation (a view of its state row, the scratch, the tables): about
20 pairs of locked instructions per sub-env, which each drain the store buffer, a third of the
step's time.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba.core import types
from numba.extending import intrinsic

from fricbench.axis import plant as PL
from fricbench.axis.kernel import (
    FASTMATH,
    P_KT,
    P_TS,
    S_IAPP,
    S_XFB,
    S_XFB_PREV,
    S_XMEAS,
    advance_axis_with,
    gains,
)

__all__ = ["N_TABLE_FEATURES", "reference_features", "step_reward", "vector_step",
           "vector_step_rows", "vector_step_shared"]

N_TABLE_FEATURES = 3
"""Scaled reference features per sample in :func:`reference_features`'s table."""


def reference_features(X: np.ndarray, V: np.ndarray, A: np.ndarray,
                       inv: np.ndarray) -> np.ndarray:
    """The observation's reference features of every sample, flattened: for row ``i``,
    sample ``k``, entries ``(i L + k) * 3 + (0, 1, 2)`` hold ``x_r / x_s, v_r / v_s,
    a_r / a_s`` as float32 (``inv``: the reciprocals of the scales, as
    :func:`fricbench.gym.task.observe_row` takes them).

    Each is the float64 product rounded once to float32, as the observation stores it: the
    step copies them instead of scaling and rounding 13 values per sub-env (the current
    sample's three and the preview's velocity and acceleration), which cost about a tenth of
    the step at 4096 sub-envs.
    """
    table = np.empty(X.shape + (N_TABLE_FEATURES,), dtype=np.float32)
    table[..., 0] = X * inv[1]
    table[..., 1] = V * inv[2]
    table[..., 2] = A * inv[3]
    return table.reshape(-1)


@intrinsic
def _fma(typingctx, a, b, c):  # type: ignore[no-untyped-def]
    """``a * b + c`` rounded once (``llvm.fma``)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        return builder.fma(*args)

    return sig, codegen


# fastmath=False said explicitly: a function called from a fast-math one inherits its flags
@numba.njit(cache=True, fastmath=False)
def step_reward(d: float, inv_e: float, e_s: float, inv_rs: float, a: float,
                w: float) -> float:
    """``r = -(e / r_s)^2 - w a^2`` of one sub-env step, with ``d = x_ref - x_meas`` (m),
    ``inv_e = 1 / e_s`` (the error feature's scale), ``inv_rs = 1 / r_s`` (the reward's error
    scale) and ``a`` the clipped action.

    The fused step wrote ``e = (d / e_s) (e_s / r_s)``, ``r = -e^2 - w a^2`` and let fast-math
    choose the order; its compiler took ``e = ((1 / e_s) e_s) d (1 / r_s)`` and fused the square
    into the subtraction (``-e^2 - (a^2) w`` rounded once). That order is written out here, and
    compiled without fast-math so that no code around it can change it: the rewards (those PPO
    trains on) stay what they were, bit for bit.
    """
    e = ((inv_e * e_s) * d) * inv_rs
    # r = -e^2 - (a^2) w, one rounding
    return _fma(-e, e, -((a * a) * w))  # type: ignore[call-arg]


# compiled only inlined into the two entry points below, which fix ``shared``
@numba.njit(cache=True, inline="always", fastmath=FASTMATH)
def vector_step(P: np.ndarray, shared: bool, S: np.ndarray, X: np.ndarray, V: np.ndarray,
                A: np.ndarray, F: np.ndarray, lengths: np.ndarray, ref_id: np.ndarray,
                k: np.ndarray,
                action: np.ndarray, hold: np.ndarray, force_action: bool, action_scale: float,
                draws: np.ndarray, preview: np.ndarray, scales: np.ndarray, inv: np.ndarray,
                reward_error_scale: float, action_weight: float, prev_action: np.ndarray,
                work: np.ndarray, status: np.ndarray, obs: np.ndarray, reward: np.ndarray,
                truncated: np.ndarray) -> int:
    """Advance every sub-env that is not held by one control sample.

    Called through :func:`vector_step_shared` or :func:`vector_step_rows`, compiled for one
    value of ``shared`` each (the other path compiled out).

    Parameters
    ----------
    P, S : ndarray
        Packed parameters and states of the ``N`` axes (kernel layout); ``S`` is updated.
    shared : bool
        Every row of ``P`` is the same (friction not redrawn per sub-env): the constants of
        the first are unpacked once per call and it stands for every sub-env's row. A
        constant in each entry point.
    X, V, A : ndarray, shape (R, L)
        Padded reference tables; sub-env ``n`` follows row ``ref_id[n]`` at sample ``k[n]``.
    F : ndarray of float32, shape (R * L * N_TABLE_FEATURES,)
        The scaled reference features of every sample (:func:`reference_features`).
    lengths : ndarray of int64, shape (R,)
        Samples of each reference (the episode truncates at ``lengths - 1``).
    ref_id, k : ndarray of int64, shape (N,)
        Reference row and sample index of each sub-env; ``k`` is advanced.
    action : ndarray, shape (N,)
        Raw actions; clipped to [-1, 1] (NaN/inf: nothing is changed and ``-1 - n`` is returned
        for the first bad row ``n``).
    hold : ndarray of bool, shape (N,)
        Rows that were just reset (Gymnasium ``NEXT_STEP`` autoreset): they do not move, report
        their reset observation, reward 0 and no truncation.
    force_action : bool
        Action is a force at the velocity-loop output (else a reference offset).
    action_scale : float
        N (force) or m (offset) per unit action.
    draws : ndarray, shape (N,)
        Standard normal draws for the measurement noise of this step.
    preview : ndarray of uint64, shape (n_preview,)
        Offsets of the preview points in ``F``: :data:`N_TABLE_FEATURES` times their sample
        offsets
        (:func:`fricbench.gym.task.preview_offsets`).
    scales, inv : ndarray
        Observation scales (:func:`fricbench.gym.task.obs_scales`) and their reciprocals.
    reward_error_scale, action_weight : float
        ``r = -(e / reward_error_scale)^2 - action_weight a^2`` with ``e`` the measured error
        (:func:`step_reward`).
    prev_action : ndarray, shape (N,)
        Updated with the applied (clipped) action.
    work : ndarray, shape (10, 1, 1)
        Scratch for the kernel's inputs and outputs, one sub-env at a time (a row per sub-env
        would be ten more arrays streamed through the cache at every step).
    status : ndarray of int64, shape (N,)
        Kernel status; non-zero for an axis whose state diverged.
    obs : ndarray of float32, shape (N, n_features)
    reward : ndarray, shape (N,)
    truncated : ndarray of bool, shape (N,)

    Returns
    -------
    int
        0 on success, ``1 + n`` for the first diverged axis ``n``, ``-1 - n`` for the first
        non-finite action ``n`` (nothing changed).
    """
    n_env = S.shape[0]
    for n in range(n_env):
        if not hold[n] and not math.isfinite(action[n]):
            return -1 - n
    xr, vr, ar, u_force, u_off, noise = work[0], work[1], work[2], work[3], work[4], work[5]
    x_true, x_meas, force, friction = work[6], work[7], work[8], work[9]
    inv_e, e_s = inv[0], scales[0]
    inv_rs = 1.0 / reward_error_scale
    first_bad = 0
    n_samples = X.shape[1]
    n_prev = preview.shape[0]
    # unpacking a plant row (divisions, branches) costs a third of a sample: done once when
    # the rows share one plant, else per row as the kernel's drivers do; the shared row also
    # stands for every sub-env's in the gains and the observation, and its gains are unpacked
    # into scalars here (not read from the row by each sub-env: the compiler cannot move an
    # array read past the state writes), so that Ts / Ti and the reciprocals of Ts and Kt are
    # computed once per step
    p0 = P[0]
    c = PL.constants(p0)
    g = gains(p0)
    for n in range(n_env):
        i = ref_id[n]
        if hold[n]:
            a = 0.0
        else:
            a = min(1.0, max(-1.0, action[n]))
            kk = k[n]
            # the kernel's inputs and outputs for this sub-env: one scratch row (0) for all
            xr[0, 0] = X[i, kk]
            vr[0, 0] = V[i, kk]
            ar[0, 0] = A[i, kk]
            if force_action:
                u_force[0, 0] = a * action_scale
                u_off[0, 0] = 0.0
            else:
                u_force[0, 0] = 0.0
                u_off[0, 0] = a * action_scale
            noise[0, 0] = draws[n]
            if shared:
                advance_axis_with(c, g, p0, n, 0, S, xr, vr, ar, u_force, u_off, noise, x_true,
                                  x_meas, force, friction, status)
            else:
                p = P[n]
                advance_axis_with(PL.constants(p), gains(p), p, n, 0, S, xr, vr, ar, u_force,
                                  u_off, noise, x_true, x_meas, force, friction, status)
            if status[n] != 0 and first_bad == 0:
                first_bad = n + 1
            k[n] = kk + 1
        prev_action[n] = a
        kk = k[n]
        # the observation (fricbench.gym.task.observe_row's layout and arithmetic), its
        # reference features copied from F; indices unsigned: numba then emits no negative-
        # index wrap-around, of which each of the preview's reads paid one
        p = p0 if shared else P[n]
        base = np.uint64((i * n_samples + kk) * N_TABLE_FEATURES)
        obs[n, 0] = (X[i, kk] - S[n, S_XMEAS]) * inv[0]
        obs[n, 1] = F[base]
        obs[n, 2] = F[base + np.uint64(1)]
        obs[n, 3] = F[base + np.uint64(2)]
        obs[n, 4] = (S[n, S_XFB] - S[n, S_XFB_PREV]) / p[P_TS] * inv[2]
        obs[n, 5] = a
        obs[n, 6] = p[P_KT] * S[n, S_IAPP] * inv[4]
        for j in range(n_prev):
            q = base + preview[j]
            obs[n, 7 + j] = F[q + np.uint64(1)]
            obs[n, 7 + n_prev + j] = F[q + np.uint64(2)]
        if hold[n]:
            reward[n] = 0.0
            truncated[n] = False
        else:
            reward[n] = step_reward(X[i, kk] - S[n, S_XMEAS], inv_e, e_s, inv_rs, a,
                                    action_weight)
            truncated[n] = kk >= lengths[i] - 1
    return first_bad


# Two entry points, one per plant layout, each with the other's path compiled out: in one
# function the two copies of the inlined kernel body (a few kB of code each) cost the shared
# path about 6 % of its time (9 ns per sub-env step at 4096 PaperAxis-v0 sub-envs), its register
# allocation and code layout made for both. _nrt=False: numba's (underscored, unstubbed) option
# for a function that allocates nothing.
@numba.njit(cache=True, fastmath=FASTMATH, _nrt=False)  # type: ignore[call-overload]
def vector_step_shared(P: np.ndarray, S: np.ndarray, X: np.ndarray, V: np.ndarray,
                       A: np.ndarray, F: np.ndarray, lengths: np.ndarray, ref_id: np.ndarray,
                       k: np.ndarray, action: np.ndarray, hold: np.ndarray, force_action: bool,
                       action_scale: float, draws: np.ndarray, preview: np.ndarray,
                       scales: np.ndarray, inv: np.ndarray, reward_error_scale: float,
                       action_weight: float, prev_action: np.ndarray, work: np.ndarray,
                       status: np.ndarray, obs: np.ndarray, reward: np.ndarray,
                       truncated: np.ndarray) -> int:
    """:func:`vector_step` with ``shared=True``: every row of ``P`` is the same."""
    return vector_step(P, True, S, X, V, A, F, lengths, ref_id, k, action, hold, force_action,
                       action_scale, draws, preview, scales, inv, reward_error_scale,
                       action_weight, prev_action, work, status, obs, reward, truncated)


@numba.njit(cache=True, fastmath=FASTMATH, _nrt=False)  # type: ignore[call-overload]
def vector_step_rows(P: np.ndarray, S: np.ndarray, X: np.ndarray, V: np.ndarray,
                     A: np.ndarray, F: np.ndarray, lengths: np.ndarray, ref_id: np.ndarray,
                     k: np.ndarray, action: np.ndarray, hold: np.ndarray, force_action: bool,
                     action_scale: float, draws: np.ndarray, preview: np.ndarray,
                     scales: np.ndarray, inv: np.ndarray, reward_error_scale: float,
                     action_weight: float, prev_action: np.ndarray, work: np.ndarray,
                     status: np.ndarray, obs: np.ndarray, reward: np.ndarray,
                     truncated: np.ndarray) -> int:
    """:func:`vector_step` with ``shared=False``: each sub-env's plant from its own row."""
    return vector_step(P, False, S, X, V, A, F, lengths, ref_id, k, action, hold, force_action,
                       action_scale, draws, preview, scales, inv, reward_error_scale,
                       action_weight, prev_action, work, status, obs, reward, truncated)
