"""``fricbench perf``: throughput of the env, the vector env and ``simulate``, with references
measured in the same run (Gymnasium's Pendulum-v1, python-control, and for the vector env the
bare kernel over the same axes, states and samples), because the machines are shared and
noisy: the ratios are what to read. Training throughput (env + policy: PPO's
rollouts and updates) is measured on the native vector env and, for the ratio, on
stable-baselines3's ``DummyVecEnv`` of scalar envs."""

from __future__ import annotations

import time
import tracemalloc
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["PERF_KEYS", "measure_performance"]

PERF_KEYS = ("env_steps_per_s", "pendulum_steps_per_s", "vector_env_steps_per_s",
             "kernel_samples_per_s", "vector_env_to_kernel", "simulate_samples_per_s",
             "python_control_samples_per_s", "train_steps_per_s", "train_dummy_steps_per_s",
             "rollout_steps_per_s", "rollout_dummy_steps_per_s", "vector_env_to_simulate")

TRAIN_ENV = "fricbench/RandomFriction-v0"
"""The env the training throughput is measured on (``fricbench train``'s default)."""


def _best_rate(work: Callable[[], int], repeats: int) -> float:
    best = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        n = work()
        best = max(best, n / (time.perf_counter() - t0))
    return best


def _env_rate(env_id: str, steps: int, repeats: int) -> float:
    import gymnasium as gym

    env = gym.make(env_id)
    zero = np.zeros(env.action_space.shape or (), dtype=np.float32)
    env.reset(seed=0)
    env.step(zero)

    def work() -> int:
        for _ in range(steps):
            _, _, term, trunc, _ = env.step(zero)
            if term or trunc:
                env.reset()
        return steps

    rate = _best_rate(work, repeats)
    env.close()
    return rate


def _vector_rate(num_envs: int, warmup: int, steps: int, repeats: int
                 ) -> tuple[float, float, float]:
    """Steps/s of the native vector env, samples/s of the bare kernel over the same work, and
    the env's peak traced memory in MB.

    The env is reset (``seed=0``) and stepped ``warmup`` times untimed (the first samples of
    the references start from rest, where a stuck axis costs the kernel half of what a moving
    one does; past them the motion is that of an episode). Then, ``repeats`` times, ``steps``
    steps of zero actions are timed, and the kernel (:meth:`fricbench.axis.AxisBatch.run`,
    what ``simulate`` and the benchmark runner call) right after them, from the same
    ``num_envs`` states over the same reference samples in one call: the same plant, the same
    batch, the same samples, so the ratio is what the env adds (a call per sample, actions,
    observations, rewards). Each rate is the best of its repeats; the two alternate, so that a
    busy spell of a shared machine slows both. The kernel's final states must equal the env's,
    or the comparison is refused.

    Memory is traced in a separate short pass: tracemalloc hooks every numpy allocation and
    would slow the timed loop.
    """
    import gymnasium as gym

    from fricbench.axis import AxisBatch

    def build() -> tuple[Any, np.ndarray]:
        venv = gym.make_vec("fricbench/PaperAxis-v0", num_envs=num_envs,
                            vectorization_mode="vector_entry_point")
        zero = np.zeros((num_envs, 1), dtype=np.float32)
        venv.reset(seed=0)
        venv.step(zero)
        return venv, zero

    tracemalloc.start()
    venv, zero = build()
    for _ in range(10):
        venv.step(zero)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    venv.close()
    venv, zero = build()
    env = venv.unwrapped
    # every sub-env stays within its episode (no autoreset inside the timed steps): an episode
    # of L samples truncates at its step L - 1
    samples = warmup + repeats * steps
    shortest = int(env._len.min()) - 1
    if samples > shortest:
        raise ValueError(f"warmup + repeats * steps = {samples} steps: expected at most "
                         f"{shortest} (the env's shortest episode)")
    venv.reset(seed=0)
    for _ in range(warmup):
        venv.step(zero)
    batch = AxisBatch(env.axis, n=num_envs)
    rate, kernel = 0.0, 0.0
    for _ in range(repeats):
        batch.S[:] = env._batch.S
        cols = env._k[:, None] + np.arange(steps)
        rows = env._ref_id[:, None]
        xr, vr, ar = (np.ascontiguousarray(table[rows, cols])
                      for table in (env._X, env._V, env._A))
        t0 = time.perf_counter()
        for _ in range(steps):
            venv.step(zero)
        rate = max(rate, steps * num_envs / (time.perf_counter() - t0))
        t0 = time.perf_counter()
        batch.run(xr, vr, ar)
        kernel = max(kernel, steps * num_envs / (time.perf_counter() - t0))
        if not np.array_equal(batch.S, env._batch.S):
            # seen after an edit to a numba-inlined function: the disk cache of the module
            # that inlines it keeps the old body (numba does not track the dependency)
            raise RuntimeError("the kernel's run did not reproduce the vector env's steps, so "
                               "the two rates would not measure the same work; if fricbench's "
                               "sources were edited, clear numba's disk cache (make clean-cache) "
                               "and run again")
    venv.close()
    return rate, kernel, peak / 2**20


def _simulate_rate(repeats: int) -> float:
    from fricbench.axis import Axis, simulate
    from fricbench.trajectories import make_trajectory

    ref = make_trajectory("reversal_sine")
    axis = Axis()
    simulate(axis, ref)
    return _best_rate(lambda: (simulate(axis, ref), ref.n_samples)[1], repeats)


def _python_control_rate(horizon: float) -> float:
    """The default axis's loop with the same Stribeck friction as a python-control ``nlsys``.

    python-control integrates continuous systems with ``solve_ivp``, so the sampled PI
    controller is written in continuous form and the friction sign is smoothed with ``tanh``
    (its solver cannot stick): the same loop as far as python-control can express it.
    """
    import control

    from fricbench.axis import Axis

    axis = Axis()
    c, m, f = axis.controller, axis.mechanics, axis.friction.kernel_params()
    gain = c.kt * c.kv
    eps = 1e-5  # m/s: tanh smoothing velocity (a tenth of the 0.1 mm/s resolution we care for)

    def updfcn(t: float, x: np.ndarray, u: np.ndarray, params: dict[str, Any]) -> np.ndarray:
        pos, vel, integ = x
        xr, vr = u
        e_v = c.kp * (xr - pos) + c.kvff * vr - vel
        force = np.clip(gain * (e_v + integ / c.ti), -c.kt * c.i_max, c.kt * c.i_max)
        speed = abs(vel)
        level = f["fc"] + (f["fs"] - f["fc"]) * np.exp(-((speed / f["vs"]) ** f["delta"]))
        fric = level * np.tanh(vel / eps) + f["fv"] * vel
        return np.array([vel, (force - m.damping * vel - fric) / m.mass, e_v])

    sys = control.nlsys(updfcn, None, inputs=["x_ref", "v_ref"], outputs=["x", "v", "I"],
                        states=["x", "v", "I"], name="axis_pc")
    t = np.arange(0.0, horizon, c.ts)
    # reversals inside the horizon: that is where friction (and the solver) works hardest
    vref = 0.01 * np.sin(2 * np.pi * 10.0 * t)
    xref = np.cumsum(vref) * c.ts
    t0 = time.perf_counter()
    control.input_output_response(sys, t, [xref, vref], X0=[0.0, 0.0, 0.0])
    return t.size / (time.perf_counter() - t0)


def _train_rate(vec_env: str, rollouts: int, repeats: int) -> tuple[float, float]:
    """Env steps/s of ``PPO.learn``, and of its rollouts alone (env + policy inference), with
    ``fricbench train``'s PPO settings (8 envs, 10 epochs of 256-sample minibatches; rollouts
    of 128 steps per env instead of 1024: the update costs the same per step) on
    :data:`TRAIN_ENV` vectorised as ``vec_env``, one torch thread; best of ``repeats``.

    The env's construction and a first rollout and update (torch and numba warm-up) are not
    timed.
    """
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    from fricbench.compensators.train import HYPERPARAMS, make_training_env

    class RolloutClock(BaseCallback):
        """Adds up the wall time of the rollouts."""

        seconds = 0.0

        def _on_rollout_start(self) -> None:
            self._t0 = time.perf_counter()

        def _on_rollout_end(self) -> None:
            self.seconds += time.perf_counter() - self._t0

        def _on_step(self) -> bool:
            return True

    hp = dict(HYPERPARAMS["ppo"])
    n_envs, pool = int(hp.pop("n_envs")), int(hp.pop("reference_pool"))
    hp["n_steps"] = 128
    steps = rollouts * n_envs * hp["n_steps"]
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        vec = make_training_env(TRAIN_ENV, n_envs=n_envs, seed=0, vec_env=vec_env,
                                reference_pool=min(pool, 4))
        model = PPO("MlpPolicy", vec, seed=0, device="cpu", **hp)
        model.learn(n_envs * hp["n_steps"])
        learn, rollout = 0.0, 0.0
        for _ in range(repeats):
            clock = RolloutClock()
            t0 = time.perf_counter()
            model.learn(steps, callback=clock, reset_num_timesteps=False)
            learn = max(learn, steps / (time.perf_counter() - t0))
            rollout = max(rollout, steps / clock.seconds)
        vec.close()
    finally:
        torch.set_num_threads(threads)
    return learn, rollout


def measure_performance(quick: bool = False, log: Callable[[str], None] = print
                        ) -> dict[str, float]:
    """Measure every figure of :data:`PERF_KEYS` in one run; logs progress and memory."""
    steps = 5000 if quick else 20000
    repeats = 2 if quick else 3
    log("perf: Pendulum-v1 reference ...")
    pendulum = _env_rate("Pendulum-v1", steps, repeats)
    log("perf: fricbench/PaperAxis-v0 through gymnasium.make ...")
    env = _env_rate("fricbench/PaperAxis-v0", steps, repeats)
    log("perf: native vector env, 4096 envs, and the kernel on the same samples ...")
    vec, kernel, peak_mb = _vector_rate(4096, 500 if quick else 1000, 50 if quick else 100,
                                        4 if quick else 10)
    log("perf: simulate (reversal_sine, default axis) ...")
    sim = _simulate_rate(3 if quick else 5)
    log("perf: python-control input_output_response ...")
    pc = _python_control_rate(0.05 if quick else 0.2)
    log(f"perf: PPO training on {TRAIN_ENV}, 8 envs: native vector env, then DummyVecEnv ...")
    train, rollout = _train_rate("native", 1, 1 if quick else 2)
    train_dummy, rollout_dummy = _train_rate("dummy", 1, 1 if quick else 2)
    result = {"env_steps_per_s": env, "pendulum_steps_per_s": pendulum,
              "vector_env_steps_per_s": vec, "kernel_samples_per_s": kernel,
              # the vector env's overhead: its steps per second per sample of the bare kernel
              # stepping the same axes over the same samples
              "vector_env_to_kernel": vec / kernel, "simulate_samples_per_s": sim,
              "python_control_samples_per_s": pc, "train_steps_per_s": train,
              "train_dummy_steps_per_s": train_dummy, "rollout_steps_per_s": rollout,
              "rollout_dummy_steps_per_s": rollout_dummy,
              # against simulate's own run (another axis, another motion: not the same work)
              "vector_env_to_simulate": vec / sim}
    log(f"perf: vector env peak memory at 4096 envs (tracemalloc): {peak_mb:.1f} MB "
        f"(target < 500 MB: {'met' if peak_mb < 500.0 else 'missed'})")
    return result


def _met(value: float, target: float) -> str:
    """``"met"`` when ``value >= target``, else ``"missed"``."""
    return "met" if value >= target else "missed"


def format_report(r: dict[str, float]) -> str:
    """Human-readable table with each figure against its target, met or missed."""
    to_pendulum = r["env_steps_per_s"] / r["pendulum_steps_per_s"]
    to_control = r["simulate_samples_per_s"] / r["python_control_samples_per_s"]
    rows = [
        ("env_steps_per_s", r["env_steps_per_s"],
         f"{to_pendulum:.2f} x Pendulum (target >= 0.5: {_met(to_pendulum, 0.5)})"),
        ("pendulum_steps_per_s", r["pendulum_steps_per_s"], "reference"),
        ("vector_env_steps_per_s", r["vector_env_steps_per_s"],
         f"{r['vector_env_to_kernel']:.2f} x the kernel on the same samples (target >= 0.8: "
         f"{_met(r['vector_env_to_kernel'], 0.8)}); {r['vector_env_to_simulate']:.2f} x "
         "simulate"),
        ("kernel_samples_per_s", r["kernel_samples_per_s"],
         "reference: AxisBatch.run from the vector env's states over its samples, 4096 axes"),
        ("simulate_samples_per_s", r["simulate_samples_per_s"],
         f"target >= 1,000,000: {_met(r['simulate_samples_per_s'], 1e6)}"),
        ("python_control_samples_per_s", r["python_control_samples_per_s"],
         f"simulate is {to_control:.0f} x this (target >= 1000 x: {_met(to_control, 1000.0)})"),
        ("train_steps_per_s", r["train_steps_per_s"],
         f"PPO learn, 8 native envs: {r['train_steps_per_s'] / r['train_dummy_steps_per_s']:.2f}"
         " x the DummyVecEnv"),
        ("train_dummy_steps_per_s", r["train_dummy_steps_per_s"],
         "reference: PPO learn, DummyVecEnv of 8 scalar envs"),
        ("rollout_steps_per_s", r["rollout_steps_per_s"],
         "its rollouts (env + policy): "
         f"{r['rollout_steps_per_s'] / r['rollout_dummy_steps_per_s']:.2f} x the DummyVecEnv's"),
        ("rollout_dummy_steps_per_s", r["rollout_dummy_steps_per_s"],
         "reference: the DummyVecEnv's rollouts"),
    ]
    width = max(len(k) for k, _, _ in rows)
    return "\n".join(f"{k:<{width}}  {v:>14,.0f}  {note}" for k, v, note in rows)
