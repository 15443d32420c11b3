"""Every array the vector env, the scalar env and the kernel return over fixed rollouts,
recorded to compare a change bit for bit (not a test: run it before and after).

    python tests/gym/record_rollouts.py record before.npz    # at the old commit
    python tests/gym/record_rollouts.py record after.npz     # at the new one
    python tests/gym/record_rollouts.py compare before.npz after.npz

Recorded: the vector env (37 sub-envs, fixed seeds, random actions out of range too, float32
and float64 alternately) on each registered single-axis env and three axes with effects
(compliance and delay; two-body backlash with motion heating and a table encoder; Dahl), on
its own references (250 steps) and on short ones (400 steps, many autoresets) in next-step and
same-step modes, with the shared and the per-row plant: every observation, reward,
termination, truncation, final observation and mask, and the final states. Also a scalar env's
rollout and the kernel's outputs on random inputs for each axis. Clear numba's cache between
the two records (``make clean-cache``) when the change touches an inlined function.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import Any

import numpy as np

from fricbench.axis import Axis, AxisBatch
from fricbench.axis.params import Effects
from fricbench.gym import ServoAxisEnv, get_spec
from fricbench.gym.task import TaskConfig, TrajectoryChoice
from fricbench.gym.vector import ServoAxisVectorEnv

ENVS = ("fricbench/PaperAxis-v0", "fricbench/PaperAxisShifted-v0", "fricbench/LuGreAxis-v0",
        "fricbench/EMPS-v0", "fricbench/DCMotor-v0", "fricbench/RandomFriction-v0")


def _effects_axis(**changes: Any) -> Axis:
    axis = get_spec("fricbench/PaperAxis-v0").axis.with_controller(kv=150.0)
    effects = dict(backlash=2e-6, cogging_amplitude=20.0, friction_gradient=0.5,
                   coulomb_asymmetry=30.0, viscous_asymmetry=20.0, friction_variation=0.1,
                   thermal_drift=5e-6, thermal_time_constant=0.5, quantization=1e-7,
                   noise_std=2e-7, delay_samples=1, compliance_load_fraction=0.3,
                   compliance_frequency=120.0, compliance_damping=0.2)
    effects.update(changes)
    return replace(axis, effects=Effects(**effects))


def _cases() -> dict[str, tuple[Axis, TaskConfig]]:
    cases = {eid: (get_spec(eid).axis, get_spec(eid).task) for eid in ENVS}
    paper = get_spec("fricbench/PaperAxis-v0").task
    cases["effects"] = (_effects_axis(), replace(paper, action="offset", action_scale=1e-5))
    cases["twobody"] = (_effects_axis(compliance_load_fraction=0.0, backlash=5e-6,
                                      backlash_load_fraction=0.4, thermal_heating_speed=0.01,
                                      measurement="table", delay_samples=2), paper)
    cases["dahl"] = (get_spec("fricbench/PaperAxis-v0").axis.with_friction(
        "dahl", fc=300.0, sigma0=1e7), paper)
    return cases


def _vector(out: dict[str, np.ndarray], key: str, axis: Axis, task: TaskConfig, mode: str,
            per_row: bool, steps: int) -> None:
    n = 37
    venv = ServoAxisVectorEnv(num_envs=n, axis=axis, task=task, reference_pool=3, seed=5,
                              autoreset_mode=mode)
    if per_row:
        venv._batch.uniform = False
    rng = np.random.default_rng(11)
    out[f"{key}|reset_obs"] = venv.reset(seed=3)[0]
    rec: dict[str, list[np.ndarray]] = {k: [] for k in ("obs", "rew", "term", "trunc")}
    finals = []
    for t in range(steps):
        a = rng.uniform(-1.5, 1.5, (n, 1))
        o, r, term, trunc, info = venv.step(a.astype(np.float32) if t % 2 else a)
        for name, arr in zip(rec, (o, r, term, trunc), strict=True):
            rec[name].append(arr.copy())
        if info:
            for i in np.flatnonzero(info["_final_obs"]):
                finals.append(np.concatenate([[t, i], info["final_obs"][i]]))
            out[f"{key}|mask{t}"] = np.stack([info["_final_obs"], info["_final_info"]])
    for name, arrs in rec.items():
        out[f"{key}|{name}"] = np.stack(arrs)
    out[f"{key}|finals"] = np.array(finals) if finals else np.zeros(0)
    out[f"{key}|S"] = venv._batch.S.copy()
    out[f"{key}|k"] = venv._k.copy()


def _scalar(out: dict[str, np.ndarray], name: str, axis: Axis, task: TaskConfig) -> None:
    env = ServoAxisEnv(axis=axis, task=task)
    rng = np.random.default_rng(4)
    seq = [env.reset(seed=2)[0]]
    rewards = []
    for _ in range(300):
        o, r, term, trunc, _ = env.step(rng.uniform(-1.5, 1.5, (1,)))
        seq.append(o)
        rewards.append(r)
        if term or trunc:
            seq.append(env.reset()[0])
    out[f"{name}|scalar|obs"] = np.stack(seq)
    out[f"{name}|scalar|rew"] = np.array(rewards)


def _kernel(out: dict[str, np.ndarray], name: str, axis: Axis) -> None:
    batch = AxisBatch(axis, n=5)
    rng = np.random.default_rng(9)
    batch.reset(np.zeros(5), np.zeros(5))
    ts, samples = axis.controller.ts, 500
    t = np.arange(samples) * ts
    xr = np.stack([0.01 * np.sin(2 * np.pi * (1 + j) * t) for j in range(5)])
    vr = np.gradient(xr, axis=1) / ts
    ar = np.gradient(vr, axis=1) / ts
    u_force = rng.normal(0, 50, (5, samples))
    u_off = rng.normal(0, 1e-6, (5, samples))
    noise = rng.standard_normal((5, samples))
    try:
        for j, arr in enumerate(batch.run(xr, vr, ar, u_force, u_off, noise)):
            out[f"{name}|kernel|out{j}"] = arr.copy()
    except Exception as exc:  # a divergence is a result too
        out[f"{name}|kernel|exc"] = np.array(str(exc))
    out[f"{name}|kernel|S"] = batch.S.copy()


def record(path: str) -> None:
    """Record every case's arrays to ``path`` (``.npz``)."""
    out: dict[str, np.ndarray] = {}
    for name, (axis, task) in _cases().items():
        second = task.trajectories[0] if name in ("fricbench/EMPS-v0", "fricbench/DCMotor-v0") \
            else TrajectoryChoice("s_curve")
        short = replace(task, trajectories=(TrajectoryChoice("random", {"duration": 0.15}),
                                            second))
        _vector(out, f"{name}|orig|NextStep|shared", axis, task, "NextStep", False, 250)
        for mode in ("NextStep", "SameStep"):
            for per_row in (False, True):
                key = f"{name}|short|{mode}|{'row' if per_row else 'shared'}"
                _vector(out, key, axis, short, mode, per_row, 400)
        _scalar(out, name, axis, short)
        _kernel(out, name, axis)
    np.savez_compressed(path, **out)
    print(f"recorded {len(out)} arrays")


def compare(a_path: str, b_path: str) -> int:
    """Print the arrays that differ (dtype, shape or any bit); 1 if any does."""
    a, b = np.load(a_path), np.load(b_path)
    if set(a.files) != set(b.files):
        print("different arrays recorded:", sorted(set(a.files) ^ set(b.files)))
        return 1
    bad = [k for k in a.files if a[k].dtype != b[k].dtype or a[k].shape != b[k].shape
           or a[k].tobytes() != b[k].tobytes()]
    for k in bad[:30]:
        print("differs:", k)
    print(f"{len(a.files)} arrays, {len(bad)} differ")
    return 1 if bad else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "record":
        record(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        sys.exit(compare(sys.argv[2], sys.argv[3]))
    else:
        sys.exit(__doc__)
