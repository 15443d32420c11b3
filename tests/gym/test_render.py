"""``ServoAxisEnv.render()``: frames, what they show, human mode's frame rate and headless warning.

Speed is not timed here (``python -m fricbench.gym.render_benchmark`` measures it).
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

from fricbench.gym import ServoAxisEnv, get_spec
from fricbench.gym.render import AxisFigure
from fricbench.trajectories import Reference

TS = 1e-3


def short_move(duration: float = 0.5) -> Reference:
    """A smooth 0.5 s back-and-forth (starts, stops and a reversal), sampled at 1 ms."""
    t = np.arange(int(round(duration / TS)) + 1) * TS
    return Reference.from_positions(t, 2e-3 * np.sin(np.pi * t / duration) ** 2, "short")


def paper_env(render_mode: str) -> ServoAxisEnv:
    spec = get_spec("fricbench/PaperAxis-v0")
    return ServoAxisEnv(axis=spec.axis, task=spec.task, render_mode=render_mode)


@pytest.fixture
def headless(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)


def test_frames_are_rgb_uint8_and_change_as_the_env_steps() -> None:
    env = gym.make("fricbench/PaperAxis-v0", render_mode="rgb_array")
    env.reset(seed=0, options={"trajectory": short_move()})
    first = env.render()
    assert first.ndim == 3 and first.shape[2] == 3 and first.dtype == np.uint8
    frames = [first]
    for _ in range(3):
        for _ in range(60):
            env.step(np.zeros(1, dtype=np.float32))
        frames.append(env.render())
    for a, b in zip(frames, frames[1:]):
        assert a.shape == b.shape
        assert np.any(a != b), "a frame did not change after 60 steps"
    env.close()


def test_picture_shows_the_trace_and_the_operating_point_on_the_friction_law() -> None:
    env = paper_env("rgb_array")
    env.reset(seed=0, options={"trajectory": short_move()})
    for _ in range(150):
        env.step(np.zeros(1))
    env.render()
    tr, fig = env._trace, env._fig
    assert tr is not None and fig is not None and tr.k == 150
    t, e = fig.lines_e[0].get_data()
    np.testing.assert_array_equal(t, tr.t[:151])
    np.testing.assert_array_equal(e, tr.error[0, :151] * 1e6)
    np.testing.assert_array_equal(fig.lines_x[0].get_ydata(), tr.x[0, :151] * 1e3)
    np.testing.assert_array_equal(fig.lines_v[0].get_ydata(), tr.v[0, :151] * 1e3)
    # the operating point is the last sample's velocity and friction force ...
    v, f = fig.points[0].get_data()
    assert v[0] == pytest.approx(env._batch.velocity[0] * 1e3)
    assert f[0] == pytest.approx(env._out[3][0, 0])
    # ... and the curve under it is the episode's friction law
    cv, cf = fig.curve.get_data()
    np.testing.assert_allclose(cf, env.current_axis.friction.force(np.asarray(cv) * 1e-3))
    assert all(c.get_xdata()[0] == pytest.approx(tr.t[150]) for c in fig.cursors)
    env.close()


def test_every_panel_names_both_of_its_axes() -> None:
    env = paper_env("rgb_array")
    env.reset(seed=0, options={"trajectory": short_move()})
    env.step(np.zeros(1))
    env.render()
    fig = env._fig
    assert fig is not None
    panels = fig.fig.axes
    assert len(panels) == 4
    for ax in panels:
        assert ax.get_xlabel() and ax.get_ylabel(), ax.get_title() or ax.get_ylabel()
    # the three time panels share the time axis and say so
    assert [ax.get_xlabel() for ax in panels[:3]] == ["time [s]"] * 3
    env.close()


def expected_human_frames(n_samples: int, fps: float) -> int:
    """Frames at t = 0, at the first sample of each 1/fps slot, and at the last sample."""
    slots = np.floor(np.arange(n_samples) * TS * fps + 1e-9).astype(int)
    n = len(np.unique(slots))
    last_is_slot_start = slots[-1] != slots[-2]
    return n + (0 if last_is_slot_start else 1)


@pytest.mark.parametrize("fps", [25, 10])
def test_human_mode_draws_by_simulated_time(headless: None, monkeypatch: pytest.MonkeyPatch,
                                            fps: int) -> None:
    drawn: list[int] = []
    draw = AxisFigure.draw

    def counting(self: AxisFigure, tr):  # type: ignore[no-untyped-def]
        drawn.append(tr.k)
        return draw(self, tr)

    monkeypatch.setattr(AxisFigure, "draw", counting)
    env = paper_env("human")
    env.metadata = {**env.metadata, "render_fps": fps}
    ref = short_move()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env.reset(seed=0, options={"trajectory": ref})
        truncated = False
        while not truncated:
            *_, truncated, _ = env.step(np.zeros(1))
    assert len(drawn) == expected_human_frames(ref.n_samples, fps)
    # 0.5 s at 25 fps: t = 0, 0.04, ..., 0.48 and the last sample (13 + 1); at 10 fps 5 + 1
    assert len(drawn) == {25: 14, 10: 6}[fps]
    assert drawn[0] == 0 and drawn[-1] == ref.n_samples - 1
    assert drawn[1] == int(round(1.0 / (fps * TS)))
    env.close()


def test_human_mode_without_display_warns_once_and_runs(headless: None) -> None:
    env = paper_env("human")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for episode in range(2):
            env.reset(seed=episode, options={"trajectory": short_move(0.2)})
            truncated = False
            while not truncated:
                *_, truncated, _ = env.step(np.zeros(1))
        assert env.render() is None
    ours = [w for w in caught if "render_mode='human'" in str(w.message)]
    assert len(ours) == 1
    assert issubclass(ours[0].category, UserWarning)
    assert "rgb_array" in str(ours[0].message)
    assert env._fig is not None and env._fig.frames_drawn > 2
    env.close()
