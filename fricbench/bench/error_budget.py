"""What part of an env's tracking error friction makes: the leaderboard's header lines.

A compensator can only remove the error there is to remove. On the paper axis (a cascade with
velocity feedforward and a velocity integral) almost all of it is friction; on the EMPS twin (a
P position loop without feedforward, as that drive runs) almost all of it is the loop's lag
``v / kp``, which friction changes by a few percent. A table that ranks compensators says which
it is: :func:`error_budget` runs the env's nominal axis without compensation (noise free, the
env's own trajectories) beside the same axis with friction off (:func:`frictionless`), and
:func:`header_lines` writes both, and what each compensator of the table says about itself on
that env (:meth:`fricbench.compensators.base.Compensator.env_note`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from fricbench.axis import Axis
from fricbench.bench.metrics import score_run
from fricbench.friction import make_friction
from fricbench.gym import get_spec
from fricbench.gym.env import ServoAxisEnv
from fricbench.gym.task import TrajectoryChoice

__all__ = ["ErrorBudget", "error_budget", "frictionless", "header_lines"]

def frictionless(axis: Axis, damping: bool = False) -> Axis:
    """``axis`` with every friction force off: the mass in its loop alone.

    Off: the friction law (Coulomb, Stribeck, viscous, LuGre, ...), the constant load, the
    effects that are friction or a force like it (asymmetries, friction varying along the
    stroke, cogging) and, unless ``damping``, the viscous damping ``B``. Kept: the controller,
    the mass, the sensor, delays, backlash and compliance.

    Raises
    ------
    ValueError
        When the loop is unstable without the damping (an identified law may lean on it: a
        voltage-driven motor's back-EMF is damping too); ``damping=True`` keeps it.
    """
    mech = axis.mechanics if damping else replace(axis.mechanics, damping=0.0)
    return replace(axis, friction=make_friction("viscous", fv=0.0),
                   mechanics=replace(mech, load=0.0),
                   effects=replace(axis.effects, cogging_amplitude=0.0, friction_gradient=0.0,
                                   coulomb_asymmetry=0.0, viscous_asymmetry=0.0,
                                   friction_variation=0.0))


@dataclass(frozen=True)
class ErrorBudget:
    """Uncompensated error of one trajectory on an env's nominal axis, with and without
    friction (m; the contour error on a two-axis env, as the benchmark scores it)."""

    trajectory: str
    max_error: float
    max_frictionless: float
    rms_error: float
    rms_frictionless: float
    damping_kept: bool = False

    @property
    def friction_share(self) -> float:
        """Part of the max error that friction adds, ``1 - max_frictionless / max_error``."""
        return 1.0 - self.max_frictionless / self.max_error if self.max_error > 0 else 0.0


def _uncompensated(axis: Axis, env_id: str, trajectory: str) -> tuple[float, float]:
    spec = get_spec(env_id)
    choice: str | TrajectoryChoice = next(
        (c for c in spec.task.trajectories if c.id == trajectory), trajectory)
    env = ServoAxisEnv(axis=axis, task=spec.task)
    env.reset(seed=0, options={"trajectory": choice})
    ref = env.reference
    if ref is None:
        raise RuntimeError(f"{env_id}: reset gave no reference")
    x_ref = np.atleast_2d(ref.x)
    err = np.empty_like(x_ref)
    err[:, 0] = x_ref[:, 0] - env.true_position
    err[:, 1:] = env.run_actions(np.zeros((env.n_axes, ref.n_samples - 1)))
    sq = (lambda a: a[0] if env.n_axes == 1 else a)
    m = score_run(ref.t, sq(x_ref), sq(x_ref - err), sq(np.atleast_2d(ref.v)),
                  sq(np.zeros_like(x_ref)))
    return m.max_error, m.rms_error


def error_budget(env_id: str, trajectories: Sequence[str]) -> list[ErrorBudget]:
    """The uncompensated error of each trajectory on ``env_id``'s nominal, noise-free axis,
    with its friction and with :func:`frictionless`'s axis (seed 0, the env's own trajectory
    parameters, as the benchmark runs them; the damping kept where the loop needs it)."""
    axis = get_spec(env_id).axis
    try:
        bare, kept = frictionless(axis), False
    except ValueError:  # unstable without its damping
        bare, kept = frictionless(axis, damping=True), True
    out = []
    for t in trajectories:
        mx, rms = _uncompensated(axis, env_id, t)
        mx0, rms0 = _uncompensated(bare, env_id, t)
        out.append(ErrorBudget(t, mx, mx0, rms, rms0, kept))
    return out


def header_lines(env_id: str, trajectories: Sequence[str],
                 compensators: Sequence[str]) -> list[str]:
    """Markdown bullets for the head of ``env_id``'s leaderboard: its :func:`error_budget` and
    the :meth:`~fricbench.compensators.base.Compensator.env_note` of each compensator (made
    with its registered defaults). ``[]`` for an env not registered here."""
    from fricbench.compensators import make_compensator

    try:
        budget = error_budget(env_id, trajectories)
    except (KeyError, ValueError):  # an env or a trajectory not registered in this process
        return []
    cells = "; ".join(
        f"{b.trajectory} {1e6 * b.max_error:.2f} um with friction, "
        f"{1e6 * b.max_frictionless:.2f} um without (friction adds "
        f"{100 * b.friction_share:.1f} %)" for b in budget)
    off = ("friction law, load, asymmetries, position-dependent friction and cogging; the "
           "viscous damping kept, without which this loop is unstable: the linear axis in its "
           "loop" if budget and budget[0].damping_kept else
           "friction law, viscous damping, load, asymmetries, position-dependent friction and "
           "cogging: the mass in its loop alone")
    lines = [f"- What there is to remove: `none` on the env's nominal axis (noise free), max "
             f"abs(e) with its friction and with friction off ({off}, whose error is the "
             f"loop's own lag): {cells}\n"]
    for c in compensators:
        try:
            note = make_compensator(c).env_note(env_id)
        except Exception:  # noqa: BLE001 - a compensator that cannot say still gets its rows
            continue
        if note:
            lines.append(f"- {note}\n")
    return lines
