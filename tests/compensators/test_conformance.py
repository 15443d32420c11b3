"""Every registered compensator through one conformance test (fit, reset, act, errors)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from fricbench.axis import simulate
from fricbench.compensators import (
    CATEGORIES,
    EpisodeContext,
    NotFittedError,
    compensator_registry,
    make_compensator,
)
from fricbench.gym import ServoAxisEnv, get_spec
from fricbench.trajectories import make_trajectory

ENV = "fricbench/PaperAxis-v0"



def _ids() -> list[str]:
    return sorted(compensator_registry.ids())


def _env(comp: Any, env_id: str = ENV) -> ServoAxisEnv:
    spec = get_spec(env_id)
    task = spec.task
    if comp.action_mode != task.action:
        task = replace(task, action=comp.action_mode, action_scale=task.offset_scale)
    return ServoAxisEnv(axis=spec.axis, task=task)


def _context(env: ServoAxisEnv) -> EpisodeContext:
    axis, ref, mode = env.current_axis, env.reference, env.task.action

    def rehearse(u: np.ndarray, seed: int) -> Any:
        kw = {"u_force": u} if mode == "force" else {"u_offset": u}
        return simulate(axis, ref, seed=seed, **kw)

    assert ref is not None
    return EpisodeContext(reference=ref, nominal_axis=env.axis, task=env.task,
                          rehearse=rehearse)


_FITTED: dict[str, Any] = {}


def _fitted(cid: str, light: dict[str, dict[str, Any]]) -> Any:
    if cid not in _FITTED:
        comp = make_compensator(cid, **light.get(cid, {}))
        try:
            comp.fit(ENV, seed=3)
        except ImportError as exc:  # an optional dependency (e.g. the predictors) missing
            pytest.skip(f"{cid}: {exc}")
        _FITTED[cid] = comp
    return _FITTED[cid]


@pytest.mark.parametrize("cid", _ids())
def test_class_attributes(cid: str, light: dict[str, dict[str, Any]]) -> None:
    comp = make_compensator(cid, **light.get(cid, {}))
    assert comp.id == cid
    assert comp.action_mode in ("force", "offset")
    assert isinstance(comp.learns, bool)
    # an offset's range is the env's (TaskConfig.offset_scale), never a compensator's own
    assert not hasattr(type(comp), "action_scale"), cid


@pytest.mark.parametrize("cid", _ids())
def test_declares_a_category(cid: str, light: dict[str, dict[str, Any]]) -> None:
    """Every registered compensator says what it uses: trials, model, online or policy."""
    comp = make_compensator(cid, **light.get(cid, {}))
    assert type(comp).category in CATEGORIES, (cid, type(comp).category)
    # what it declares agrees with what it does: a model is fitted, trials need no fit
    if type(comp).category == "model":
        assert comp.learns
    if type(comp).category in ("trials", "online"):
        assert not comp.learns


@pytest.mark.parametrize("cid", _ids())
def test_not_fitted_raises(cid: str, light: dict[str, dict[str, Any]]) -> None:
    comp = make_compensator(cid, **light.get(cid, {}))
    env = _env(comp)
    env.reset(seed=0, options={"trajectory": "s_curve"})
    if comp.learns:
        with pytest.raises(NotFittedError, match=cid):
            comp.reset(_context(env), seed=0)
    with pytest.raises(RuntimeError):
        make_compensator(cid, **light.get(cid, {})).act(np.zeros(17))


@pytest.mark.parametrize("cid", _ids())
def test_episode_shapes_range_finite(cid: str, light: dict[str, dict[str, Any]]) -> None:
    comp = _fitted(cid, light)
    env = _env(comp)
    obs, _ = env.reset(seed=1, options={"trajectory": "s_curve"})
    comp.reset(_context(env), seed=1)
    n = 0
    while True:
        a = comp.act(obs)
        assert a.shape == (1,) and a.dtype == np.float32
        assert np.all(np.isfinite(a)) and np.all(np.abs(a) <= 1.0)
        obs, _, _, truncated, _ = env.step(a)
        n += 1
        if truncated:
            break
    assert n == env.reference.n_samples - 1
    comp.end_episode()


@pytest.mark.parametrize("cid", _ids())
def test_two_axis_circle(cid: str, light: dict[str, dict[str, Any]]) -> None:
    comp = _fitted(cid, light)
    spec = get_spec("fricbench/CircleContouring-v0")
    task = spec.task
    if comp.action_mode != task.action:
        task = replace(task, action=comp.action_mode, action_scale=task.offset_scale)
    env = ServoAxisEnv(axis=spec.axis, task=task)
    ref = make_trajectory("circle", revolutions=0.25, dwell=0.05)
    obs, _ = env.reset(seed=0, options={"trajectory": ref})
    comp.reset(_context(env), seed=0)
    for _ in range(300):
        a = comp.act(obs)
        assert a.shape == (2,) and np.all(np.isfinite(a)) and np.all(np.abs(a) <= 1.0)
        obs, *_ = env.step(a)


@pytest.mark.parametrize("cid", _ids())
def test_nan_observation_rejected(cid: str, light: dict[str, dict[str, Any]]) -> None:
    comp = _fitted(cid, light)
    env = _env(comp)
    obs, _ = env.reset(seed=0, options={"trajectory": "s_curve"})
    comp.reset(_context(env), seed=0)
    bad = obs.copy()
    bad[0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        comp.act(bad)


@pytest.mark.parametrize("cid", _ids())
def test_wrong_action_mode_rejected(cid: str, light: dict[str, dict[str, Any]]) -> None:
    comp = _fitted(cid, light)
    spec = get_spec(ENV)
    other = "offset" if comp.action_mode == "force" else "force"
    env = ServoAxisEnv(axis=spec.axis, task=replace(spec.task, action=other))
    env.reset(seed=0, options={"trajectory": "s_curve"})
    with pytest.raises(ValueError, match="actions"):
        comp.reset(_context(env), seed=0)


def test_rl_policy_files_are_not_pickles() -> None:
    """The shipped RL policies are weights + JSON; no SB3 zip is shipped."""
    from importlib import resources
    from pathlib import Path

    folder = Path(str(resources.files("fricbench").joinpath("policies")))
    assert not list(folder.glob("*.zip"))
    for cid in ("rl-sac", "rl-ppo", "rl-residual"):
        assert (folder / f"{cid}.json").is_file()
        assert (folder / f"{cid}.pt").is_file()
