"""Plants and noise per seed: the seeds differ, the nominal option is the benchmark of before."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

from fricbench.axis import simulate
from fricbench.axis.variation import BENCH_VARIATION, PlantVariation, draw_plant, nominal_told
from fricbench.bench.runner import BenchTask, fit_compensators, plant_axes, run_episode
from fricbench.compensators import make_compensator
from fricbench.gym import ServoAxisEnv, get_spec
from fricbench.trajectories import make_trajectory

PAPER = "fricbench/PaperAxis-v0"


def test_draw_plant_is_seeded_varies_and_stays_in_range() -> None:
    nominal = get_spec(PAPER).axis
    plants = [draw_plant(nominal, s) for s in range(10)]
    assert draw_plant(nominal, 3) == plants[3]  # same seed, same plant
    fcs = {p.friction.fc for p in plants}  # type: ignore[attr-defined]
    assert len(fcs) == 10
    v = BENCH_VARIATION
    for p in plants:
        assert p.controller == nominal.controller
        f, fn = p.friction, nominal.friction
        lim = math.exp(2.0 * v.friction_level) + 1e-12
        assert 1 / lim <= f.fc / fn.fc <= lim  # type: ignore[attr-defined]
        assert f.fs >= f.fc  # type: ignore[attr-defined]
        assert 1 / math.exp(0.1 + 1e-12) <= p.mechanics.mass / nominal.mechanics.mass \
            <= math.exp(0.1 + 1e-12)
        assert p.effects.noise_std == v.encoder_noise
        assert p.effects.current_noise_std == v.current_noise
    with pytest.raises(ValueError, match="seed"):
        draw_plant(nominal, -1)
    with pytest.raises(ValueError, match="friction_level"):
        PlantVariation(friction_level=-0.1)


def test_compensators_are_told_the_nominal_axis_not_the_plant() -> None:
    told, plant = plant_axes(PAPER, 4)
    nominal = get_spec(PAPER).axis
    assert told == nominal_told(nominal) and told.friction == nominal.friction
    assert plant != told
    env = ServoAxisEnv(axis=told, task=get_spec(PAPER).task, plant=plant)
    env.reset(seed=4, options={"trajectory": "s_curve"})
    assert env.episode_context().nominal_axis == told
    assert env.current_axis == plant
    assert plant_axes(PAPER, 4, nominal=True) == (nominal, nominal)


def _none(env: str, traj: str, seed: int, nominal: bool) -> float:
    comp = make_compensator("none").fit(env)
    rec = run_episode(comp, BenchTask(env, "none", traj, seed), nominal=nominal)
    assert rec.status == "ok", rec.reason
    assert rec.plant == ("nominal" if nominal else "seed")
    return rec.max_error * 1e6


def test_seeds_differ_and_nominal_reproduces_the_numbers_of_before() -> None:
    drawn = [_none(PAPER, "s_curve", s, nominal=False) for s in (0, 1, 2)]
    assert len({round(x, 6) for x in drawn}) == 3  # the per-seed numbers of `none` differ
    nominal = [_none(PAPER, "s_curve", s, nominal=True) for s in (0, 1)]
    # leaderboards/PaperAxis-v0.csv before plants were drawn: none, s_curve, every seed
    assert nominal[0] == nominal[1] == pytest.approx(24.466, abs=5e-4)


def test_nominal_kalman_reproduces_the_numbers_of_before() -> None:
    comp = make_compensator("kalman").fit(PAPER)
    rec = run_episode(comp, BenchTask(PAPER, "kalman", "s_curve", 2), nominal=True)
    assert rec.max_error * 1e6 == pytest.approx(8.372, abs=5e-4)
    assert rec.rms_error * 1e6 == pytest.approx(1.531, abs=5e-4)


def _serial(fn: Callable[..., Any], arglist: list[tuple[Any, ...]]) -> Iterator[tuple[int, Any]]:
    for i, args in enumerate(arglist):
        yield i, fn(*args)


def test_model_compensators_are_fitted_per_seed_on_its_plant() -> None:
    kw = {"friction-ff": {"n_runs": 1, "run_duration": 8.0, "v_eps_grid": (1e-4,),
                          "advance_grid": (1,)}}
    fitted = fit_compensators(["friction-ff", "none"], [PAPER], 1000, _serial, kw,
                              plant_seeds=[0, 1])
    assert set(fitted) == {(c, PAPER, s) for c in ("friction-ff", "none") for s in (0, 1)}
    f0, f1 = fitted[("friction-ff", PAPER, 0)][0], fitted[("friction-ff", PAPER, 1)][0]
    assert f0 is not None and f1 is not None
    # each learned its own machine: the plants of seeds 0 and 1 differ by ~24 % in fc
    fc0, fc1 = f0.model_.fc, f1.model_.fc  # type: ignore[attr-defined]
    true0 = draw_plant(get_spec(PAPER).axis, 0).friction.fc  # type: ignore[attr-defined]
    true1 = draw_plant(get_spec(PAPER).axis, 1).friction.fc  # type: ignore[attr-defined]
    assert abs(fc0 - true0) < abs(fc0 - true1) and abs(fc1 - true1) < abs(fc1 - true0)
    nominal = fit_compensators(["none"], [PAPER], 1000, _serial)
    assert set(nominal) == {("none", PAPER, None)}


def test_current_noise_reaches_the_reported_force_only() -> None:
    axis = get_spec(PAPER).axis
    ref = make_trajectory("s_curve", ts=axis.controller.ts)
    clean = simulate(axis, ref, seed=5)
    noisy = simulate(axis.with_effects(current_noise_std=0.05), ref, seed=5)
    np.testing.assert_array_equal(clean.x, noisy.x)  # the axis moves the same
    std = float(np.std(noisy.u - clean.u))
    assert 0.8 * 30.0 < std < 1.2 * 30.0  # kt 600 N/A x 0.05 A
    task = get_spec(PAPER).task
    obs = []
    for plant in (axis, axis.with_effects(current_noise_std=0.05)):
        env = ServoAxisEnv(axis=axis, task=task, plant=plant)
        env.reset(seed=1, options={"trajectory": "s_curve"})
        obs.append(env.step(np.zeros(1, np.float32))[0])
    diff = obs[1] - obs[0]
    assert diff[6] != 0.0 and np.all(diff[np.arange(diff.size) != 6] == 0.0)


@pytest.mark.parametrize("nominal", [True, False])
@pytest.mark.parametrize("env_id,traj", [(PAPER, "s_curve"),
                                         ("fricbench/CircleContouring-v0", "circle")])
def test_open_loop_fast_path_equals_the_step_loop(env_id: str, traj: str,
                                                  nominal: bool) -> None:
    """One kernel call for feedforward compensators: the numbers of the step loop, bit for bit
    (noise drawn in the same order on a drawn plant)."""
    kw: dict[str, dict[str, Any]] = {
        "friction-ff": {"n_runs": 1, "run_duration": 8.0, "v_eps_grid": (1e-4,),
                        "advance_grid": (1,)},
        "ilc": {"iterations": 2}}
    for cid in ("none", "friction-ff", "ilc"):
        comp = make_compensator(cid, **kw.get(cid, {})).fit(env_id, seed=1000)
        task = BenchTask(env_id, cid, traj, 3)
        fast = run_episode(comp, task, nominal=nominal, fast=True, keep_trace=True)
        loop = run_episode(comp, task, nominal=nominal, fast=False, keep_trace=True)
        assert fast.status == loop.status == "ok", (fast.reason, loop.reason)
        for name in ("max_error", "rms_error", "effort_rms"):
            assert getattr(fast, name) == getattr(loop, name), (cid, name)
        assert fast.trace_error is not None and loop.trace_error is not None
        np.testing.assert_array_equal(fast.trace_error, loop.trace_error)
    kalman = make_compensator("kalman").fit(env_id)
    kalman.reset(_context(env_id, traj))
    assert kalman.planned_actions(10) is None  # needs the observation: stepped


def _context(env_id: str, traj: str) -> Any:
    env = ServoAxisEnv(axis=get_spec(env_id).axis, task=get_spec(env_id).task)
    env.reset(seed=0, options={"trajectory": traj})
    return env.episode_context()


def test_the_bench_name_re_exports_the_axis_draw() -> None:
    import fricbench.axis.variation as variation
    import fricbench.bench.plants as plants

    for name in plants.__all__:
        assert getattr(plants, name) is getattr(variation, name), name
