"""stable-baselines3 on the native vector env: :class:`SB3VecEnv` and :func:`make_sb3_vec_env`.

stable-baselines3 refuses a Gymnasium vector env (``ValueError: The environment is of type
<class '...ServoAxisVectorEnv'>, not a Gymnasium environment``) and wraps scalar envs in its
``DummyVecEnv``, one Python ``step`` per sub-env. :class:`SB3VecEnv` gives it the native
vector env instead, all sub-envs in one compiled call per step::

    from stable_baselines3 import PPO
    from fricbench.gym.sb3 import make_sb3_vec_env

    vec = make_sb3_vec_env("fricbench/RandomFriction-v0", num_envs=8, seed=0)
    PPO("MlpPolicy", vec, seed=0).learn(10_000)

This module imports stable-baselines3 (and torch); :mod:`fricbench` does not import it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from fricbench._validation import check_int

__all__ = ["SB3VecEnv", "make_sb3_vec_env"]


def _unbatch_info(info: dict[str, Any], n: int) -> list[dict[str, Any]]:
    """Gymnasium's vector ``info`` (arrays with ``_key`` masks) as one dict per sub-env."""
    out: list[dict[str, Any]] = [{} for _ in range(n)]
    for key, value in info.items():
        if key.startswith("_") or key in ("final_obs", "final_info"):
            continue
        mask = info.get(f"_{key}")
        rows = range(n) if mask is None else np.flatnonzero(mask)
        per_env = _unbatch_info(value, n) if isinstance(value, dict) else value
        for i in rows:
            out[i][key] = per_env[i]
    return out


class SB3VecEnv(VecEnv):
    """A stable-baselines3 ``VecEnv`` over a Gymnasium vector env in ``SAME_STEP`` autoreset.

    Made for :class:`~fricbench.gym.ServoAxisVectorEnv` (:func:`make_sb3_vec_env` builds one);
    any Gymnasium vector env with ``Box`` spaces and ``metadata["autoreset_mode"]`` equal to
    ``AutoresetMode.SAME_STEP`` works. Follows the contract of stable-baselines3's
    ``DummyVecEnv``:

    - ``step`` returns ``(obs, rewards, dones, infos)``: ``dones = terminated | truncated``,
      rewards as float32, one info dict per sub-env with ``"TimeLimit.truncated"``
      (``truncated and not terminated``). A sub-env whose episode ended returns its *reset*
      observation, and its info carries ``"terminal_observation"``, the last observation of
      the finished episode (plus the final step's info entries); its reset info goes to
      ``reset_infos``.
    - The spaces are those of one sub-env.
    - ``seed(s)`` takes effect at the next ``reset``, which re-seeds the vector env with
      ``s``: the native env draws every sub-env's episodes from one generator, so only the
      first of stable-baselines3's per-env seeds ``s, s + 1, ...`` is used. Same seed and same
      actions, same rollouts bit for bit.
    - Attributes and methods (``get_attr``, ``set_attr``, ``env_method``) are the vector env's,
      shared by every sub-env: ``get_attr`` returns the one value per index asked for;
      ``set_attr`` and ``env_method`` act on all sub-envs at once and refuse ``indices`` that
      name only some. No sub-env is a ``gymnasium.Wrapper`` (``env_is_wrapped`` is all False;
      wrap the whole in ``VecMonitor`` for episode statistics).

    Parameters
    ----------
    venv : gymnasium.vector.VectorEnv
        The vector env, in ``SAME_STEP`` autoreset mode; closed by :meth:`close`.

    Raises
    ------
    TypeError
        When ``venv`` is not a Gymnasium vector env or its spaces are not ``Box``.
    ValueError
        When ``venv`` resets in another autoreset mode.
    """

    def __init__(self, venv: VectorEnv) -> None:
        if not isinstance(venv, VectorEnv):
            raise TypeError(f"venv={venv!r} ({type(venv).__name__}): expected a "
                            "gymnasium.vector.VectorEnv")
        mode = venv.metadata.get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(f"venv autoreset_mode={mode!r}: expected AutoresetMode.SAME_STEP "
                             "(stable-baselines3 expects the reset observation in the step "
                             "that ends an episode); use make_sb3_vec_env, or build the vector "
                             "env with autoreset_mode='SameStep'")
        obs_space, act_space = venv.single_observation_space, venv.single_action_space
        for name, space in (("observation", obs_space), ("action", act_space)):
            if not isinstance(space, spaces.Box):
                raise TypeError(f"venv single {name} space {space!r}: expected a Box")
        self.venv = venv
        self._actions: np.ndarray | None = None
        super().__init__(venv.num_envs, obs_space, act_space)

    # -- episodes -----------------------------------------------------------------------------
    def reset(self) -> VecEnvObs:
        """Reset every sub-env (with the seed and options set since the last reset, if any)."""
        seed = self._seeds[0]
        options = self._options[0] if any(self._options) else None
        obs, info = self.venv.reset(seed=seed, options=options)
        self.reset_infos = _unbatch_info(info, self.num_envs)
        self._reset_seeds()
        self._reset_options()
        return np.asarray(obs)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("call step_async(actions) before step_wait()")
        actions, self._actions = self._actions, None
        obs, rewards, terminated, truncated, info = self.venv.step(actions)
        terminated = np.asarray(terminated, dtype=bool)
        truncated = np.asarray(truncated, dtype=bool)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{"TimeLimit.truncated": t}
                                       for t in (truncated & ~terminated).tolist()]
        if info or dones.any():  # the native env's info is empty but when episodes end
            step_infos = _unbatch_info(info, self.num_envs)
            if dones.any():
                final_obs = info.get("final_obs")
                if final_obs is None:
                    raise RuntimeError("the vector env ended an episode without "
                                       "info['final_obs'] (not SAME_STEP autoreset?)")
                final_infos = _unbatch_info(info.get("final_info", {}), self.num_envs)
                for i in np.flatnonzero(dones).tolist():
                    # the step's own info of a finished sub-env is its reset info (SAME_STEP)
                    self.reset_infos[i] = step_infos[i]
                    step_infos[i] = final_infos[i]
                    infos[i]["terminal_observation"] = final_obs[i]
            for row, extra in enumerate(step_infos):
                infos[row].update(extra)
        return np.asarray(obs), np.asarray(rewards, dtype=np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    # -- the vector env's attributes, shared by every sub-env ----------------------------------
    def _rows(self, indices: VecEnvIndices) -> list[int]:
        """``indices`` (None: all, an int, or integers) as a checked list of sub-env rows."""
        return [check_int("indices", int(i) if isinstance(i, np.integer) else i, 0,
                          self.num_envs - 1) for i in self._get_indices(indices)]

    def _all_indices(self, indices: VecEnvIndices, what: str) -> list[int]:
        rows = self._rows(indices)
        if indices is not None and sorted(set(rows)) != list(range(self.num_envs)):
            raise ValueError(f"indices={indices!r}: {what} acts on the one vector env shared "
                             f"by all {self.num_envs} sub-envs; pass None (all)")
        return rows

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The vector env's ``attr_name``, once per index (shared by every sub-env)."""
        rows = self._rows(indices)
        value = getattr(self.venv, attr_name)
        return [value for _ in rows]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set the vector env's ``attr_name`` (for every sub-env; ``indices`` must name all)."""
        self._all_indices(indices, "set_attr")
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        """Call the vector env's method once; its result repeated per index."""
        rows = self._all_indices(indices, "env_method")
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in rows]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper],
                       indices: VecEnvIndices = None) -> list[bool]:
        """All False: the sub-envs are rows of one vector env, not wrapped envs."""
        return [False for _ in self._rows(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        raise NotImplementedError("the native vector env does not render; use ServoAxisEnv")


def make_sb3_vec_env(spec_id: str, num_envs: int = 1, *, seed: int = 0,
                     reference_pool: int = 4, **overrides: Any) -> SB3VecEnv:
    """The native vector env of ``spec_id`` as a stable-baselines3 ``VecEnv``.

    Parameters
    ----------
    spec_id : str
        A registered single-axis env id, e.g. ``"fricbench/RandomFriction-v0"``.
    num_envs : int
        Sub-envs.
    seed : int
        Seed of the reference pool and of the per-episode draws (until ``seed()`` and
        ``reset()`` replace the latter; stable-baselines3's ``seed=`` does).
    reference_pool : int
        References generated per seeded trajectory choice (``random``): each episode draws one
        from the pool.
    **overrides
        Keywords merged onto the env's spec (``trajectories``, ``friction``, ``effects``,
        ...: :func:`fricbench.gym.make_vector_env`).

    Returns
    -------
    SB3VecEnv
    """
    from fricbench.gym.specs import make_vector_env

    venv = make_vector_env(spec_id, num_envs, seed=seed, reference_pool=reference_pool,
                           autoreset_mode=AutoresetMode.SAME_STEP, **overrides)
    return SB3VecEnv(venv)

