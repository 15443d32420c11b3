"""ilc: converges over rehearsals; refuses to run without rehearsal."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fricbench.axis import simulate
from fricbench.compensators import CompensatorError, EpisodeContext
from fricbench.compensators.ilc import ForceILC, IterativeLearningControl, impulse_response
from fricbench.gym import get_spec
from fricbench.trajectories import make_trajectory


def _context(mode: str, rehearse: bool = True) -> EpisodeContext:
    spec = get_spec("fricbench/PaperAxis-v0")
    task = replace(spec.task, action=mode,
                   action_scale=1e-4 if mode == "offset" else spec.task.action_scale)
    ref = make_trajectory("s_curve")

    def run(u: np.ndarray, seed: int) -> object:
        kw = {"u_force": u} if mode == "force" else {"u_offset": u}
        return simulate(spec.axis, ref, seed=seed, **kw)

    return EpisodeContext(ref, spec.axis, task, rehearse=run if rehearse else None)


@pytest.mark.parametrize("cls", [IterativeLearningControl, ForceILC])
def test_converges(cls: type[IterativeLearningControl]) -> None:
    comp = cls(iterations=12)
    comp.reset(_context(cls.action_mode), seed=0)
    hist = [h["max_measured_um"] for h in comp.history_]
    assert len(hist) == 12
    assert min(hist[-3:]) < 0.25 * hist[0]


def test_offset_model_has_unit_dc_gain() -> None:
    axis = get_spec("fricbench/PaperAxis-v0").axis
    assert impulse_response(axis, "offset").sum() == pytest.approx(1.0, abs=1e-6)
    assert impulse_response(axis, "force").sum() == pytest.approx(0.0, abs=1e-9)


def test_needs_rehearsal() -> None:
    with pytest.raises(CompensatorError, match="rehearse"):
        IterativeLearningControl(iterations=2).reset(_context("offset", rehearse=False))


def test_validation() -> None:
    with pytest.raises(ValueError, match="gain"):
        IterativeLearningControl(gain=1.5)
    with pytest.raises(ValueError, match="keep"):
        IterativeLearningControl(keep="first")
