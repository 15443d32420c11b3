"""Environment specs: one TOML file per env id in ``envs/``, registered with Gymnasium.

A spec file holds ``id`` (``fricbench/Name-vN``), ``description``, ``benchmark`` (scored by
``fricbench bench``, default true), ``fit_on`` (the env whose training setup compensators learn
from, default itself: a different id makes the env a generalisation case), ``[axis]`` (sections
``controller``, ``mechanics``, ``friction``, ``effects`` as in :meth:`Axis.from_dict`) and
``[task]`` (:meth:`TaskConfig.from_dict`: trajectories, action, reward, observation, randomize).
Dropping a new TOML file into ``envs/`` (or a folder named by ``FRICBENCH_ENV_PATH``) adds an
environment.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import gymnasium as gym

from fricbench.axis import Axis
from fricbench.gym.task import TaskConfig
from fricbench.registry import UnknownIdError

__all__ = [
    "EnvSpecFile",
    "env_ids",
    "load_spec",
    "make_env",
    "make_vector_env",
    "register_envs",
    "spec_files",
]

_SPECS: dict[str, EnvSpecFile] = {}


@dataclass(frozen=True)
class EnvSpecFile:
    """A parsed env spec."""

    id: str
    description: str
    axis: Axis
    task: TaskConfig
    path: str
    benchmark: bool
    fit_on: str


def load_spec(path: str | Path) -> EnvSpecFile:
    """Parse and validate one TOML spec; errors name the file and the offending key."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: cannot read env spec: {exc}") from exc
    unknown = set(data) - {"id", "description", "axis", "task", "benchmark", "fit_on"}
    if unknown:
        raise ValueError(f"{path}: unknown top-level keys {sorted(unknown)}")
    env_id = data.get("id")
    if not isinstance(env_id, str) or not env_id.startswith("fricbench/") or "-v" not in env_id:
        raise ValueError(f"{path}: id={env_id!r}: expected 'fricbench/Name-vN'")
    try:
        axis = Axis.from_dict(data.get("axis", {}))
        task = TaskConfig.from_dict(data.get("task", {}))
    except (TypeError, ValueError, KeyError) as exc:
        raise ValueError(f"{path}: {exc}") from exc
    fit_on = data.get("fit_on", env_id)
    if not isinstance(fit_on, str):
        raise ValueError(f"{path}: fit_on={fit_on!r}: expected an env id")
    return EnvSpecFile(env_id, str(data.get("description", "")), axis, task, str(path),
                       bool(data.get("benchmark", True)), fit_on)


def spec_files() -> list[Path]:
    """The shipped specs (``fricbench/gym/specs`` -> the repository's ``envs/``) and any in
    ``FRICBENCH_ENV_PATH`` (``os.pathsep``-separated folders)."""
    shipped = resources.files("fricbench.gym").joinpath("specs")
    files = sorted(Path(str(shipped)).glob("*.toml"))
    for folder in filter(None, os.environ.get("FRICBENCH_ENV_PATH", "").split(os.pathsep)):
        files.extend(sorted(Path(folder).glob("*.toml")))
    return files


def register_envs() -> list[str]:
    """Register every spec with Gymnasium (idempotent); return the ids."""
    for path in spec_files():
        spec = load_spec(path)
        if spec.id in _SPECS:
            if _SPECS[spec.id].path != spec.path:
                raise ValueError(f"env id {spec.id!r} defined twice: {_SPECS[spec.id].path} and "
                                 f"{spec.path}")
            continue
        _SPECS[spec.id] = spec
        single = spec.task.trajectories and all(
            t.id != "circle" for t in spec.task.trajectories)
        gym.register(
            id=spec.id,
            entry_point="fricbench.gym.specs:make_env",
            vector_entry_point="fricbench.gym.specs:make_vector_env" if single else None,
            kwargs={"spec_id": spec.id},
        )
    return sorted(_SPECS)


def env_ids(benchmark_only: bool = False) -> list[str]:
    """Registered fricbench env ids (optionally only those the benchmark runs)."""
    register_envs()
    return sorted(i for i, s in _SPECS.items() if s.benchmark or not benchmark_only)


def get_spec(spec_id: str) -> EnvSpecFile:
    """The parsed spec of a registered id (with near-match suggestions when unknown)."""
    register_envs()
    if spec_id not in _SPECS:
        import difflib

        close = difflib.get_close_matches(spec_id, list(_SPECS), n=3, cutoff=0.4)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        raise UnknownIdError(f"unknown fricbench env id {spec_id!r}{hint}")
    return _SPECS[spec_id]


def make_env(spec_id: str, render_mode: str | None = None, **overrides: Any) -> gym.Env:
    """Entry point of every registered id: the scalar env of ``spec_id``.

    ``overrides`` may replace ``axis`` (an :class:`Axis`) or ``task`` (a :class:`TaskConfig`).
    """
    from fricbench.gym.env import ServoAxisEnv

    spec = get_spec(spec_id)
    unknown = set(overrides) - {"axis", "task"}
    if unknown:
        raise TypeError(f"make_env: unexpected arguments {sorted(unknown)}; expected axis, task")
    return ServoAxisEnv(axis=overrides.get("axis", spec.axis),
                        task=overrides.get("task", spec.task), render_mode=render_mode)


def make_vector_env(spec_id: str, num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """Vector entry point: the native :class:`ServoAxisVectorEnv` of ``spec_id``."""
    from fricbench.gym.vector import ServoAxisVectorEnv

    spec = get_spec(spec_id)
    kwargs.setdefault("axis", spec.axis)
    kwargs.setdefault("task", spec.task)
    return ServoAxisVectorEnv(num_envs=num_envs, **kwargs)
