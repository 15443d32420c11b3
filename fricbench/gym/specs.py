"""Environment specs: one TOML file per env id in ``envs/``, registered with Gymnasium.

A spec file holds ``id`` (``namespace/Name-vN``: ``fricbench/`` for the shipped specs, a
user's own namespace such as ``local/Mill-v0`` for theirs), ``description``, ``benchmark``
(scored by ``fricbench bench``, a TOML boolean, default true), ``fit_on`` (the env whose training
setup compensators learn from, default itself: a different id makes the env a generalisation
case), ``[axis]`` (sections ``controller``, ``mechanics``, ``friction``, ``effects`` as in
:meth:`Axis.from_dict`) and ``[task]`` (:meth:`TaskConfig.from_dict`: trajectories, action,
reward, observation, randomize). Dropping a new TOML file into ``envs/`` (or a folder named by
``FRICBENCH_ENV_PATH``) adds an environment.

The ids live on :data:`env_registry` (an :class:`EnvRegistry`, the project's shared
:class:`~fricbench.registry.Registry`), each with its parsed spec; :func:`env_ids`,
:func:`get_spec`, ``fricbench list``, ``fricbench bench`` and Gymnasium's registration read it.
A third-party package adds env specs through the entry-point group ``fricbench.envs``: the
entry point names a spec file's path, a parsed spec (:func:`load_spec`), or a callable that
takes the registry::

    # pyproject.toml of the package
    [project.entry-points."fricbench.envs"]
    mine = "my_pkg.envs:SPEC"            # SPEC = Path(__file__).with_name("mine.toml")
    more = "my_pkg.envs:register"        # def register(registry): registry.register_spec(path)

After ``import fricbench``, ``gym.make`` and ``fricbench bench --envs`` take its ids. A plug-in
that fails, or a malformed spec it gives, is skipped with an :class:`EnvSpecWarning`.

Every spec is validated when it is read, not at ``reset``: types, ids and sizes. Each problem
names the file, the key, the value and what was expected; unknown keys and ids come with a
"did you mean". A malformed spec is skipped with one :class:`EnvSpecWarning` and every other
env stays registered; ``fricbench list --check`` (:func:`check_specs`) reports every problem.

The trajectories of a spec are checked by a dry run of their generators at the coarse sample
time :data:`PROBE_TS` (ids, parameters, number of axes, length). At ``import fricbench`` this dry
run is done for the specs on ``FRICBENCH_ENV_PATH`` only: the shipped specs are checked by the
test suite and by ``fricbench list --check``, so the import does not get slower.

Limits (module constants):

* :data:`MAX_SPEC_BYTES`: size of a spec file.
* :data:`MAX_TRAJECTORIES`: entries of ``task.trajectories``.
* :data:`MAX_REFERENCE_SAMPLES`: reference samples of one episode on each trajectory of the set,
  summed, at the axis's sample time. ``gym.make`` generates every reference of the set (a few
  microseconds per sample), so this bounds it to seconds; at the default 1 ms it allows
  1000 s of references (the shipped sets have at most 77 s).
"""

from __future__ import annotations

import copy
import importlib.metadata
import inspect
import json
import math
import os
import re
import reprlib
import stat
import tomllib
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import MISSING, dataclass, field, fields, is_dataclass
from importlib import resources
from pathlib import Path
from typing import Any, TypeVar, cast

import gymnasium as gym
import numpy as np

from fricbench.axis import Axis, ControllerParams, Effects, MechanicsParams
from fricbench.friction import FrictionModel, friction_registry
from fricbench.gym.task import (
    ObservationConfig,
    Randomization,
    RewardConfig,
    TaskConfig,
    TrajectoryChoice,
    reference_for,
)
from fricbench.registry import Registry, did_you_mean
from fricbench.trajectories import trajectory_registry

__all__ = [
    "MAX_REFERENCE_SAMPLES",
    "MAX_SPEC_BYTES",
    "MAX_TRAJECTORIES",
    "ENV_ID_PATTERN",
    "ENV_ID_FORM",
    "PROBE_TS",
    "OVERRIDE_KEYWORDS",
    "EnvKeywordError",
    "EnvRegistry",
    "EnvSpecError",
    "EnvSpecFile",
    "EnvSpecWarning",
    "check_specs",
    "env_ids",
    "env_registry",
    "get_spec",
    "load_spec",
    "make_env",
    "make_vector_env",
    "register_envs",
    "resolve_overrides",
    "spec_files",
]

MAX_SPEC_BYTES = 1_000_000
"""Largest spec file read, bytes."""
MAX_TRAJECTORIES = 32
"""Most entries in ``task.trajectories``."""
MAX_REFERENCE_SAMPLES = 1_000_000
"""Most reference samples of a trajectory set (one episode on each, at the axis's ``ts``)."""
PROBE_TS = 0.1
"""Sample time of the load-time dry run of the trajectory generators, s."""

_TOP_KEYS = ("id", "description", "benchmark", "fit_on", "axis", "task")
_AXIS_KEYS = ("controller", "mechanics", "friction", "effects")
ENV_ID_PATTERN = re.compile(r"[A-Za-z0-9_:-]+/[A-Za-z0-9_.:-]+-v[0-9]+")
"""The form of a spec's env id, ``namespace/Name-vN``: Gymnasium's id grammar
(``gymnasium.envs.registration.ENV_ID_RE``) with the namespace and the version required, in
ASCII. The shipped specs use ``fricbench/``; a user's twin belongs in a namespace of its own."""
ENV_ID_FORM = ("'namespace/Name-vN' such as 'local/MyMill-v0' (letters, digits, '_', ':', '-' "
               "in the namespace, also '.' in the name, then a version such as -v0)")
"""What :data:`ENV_ID_PATTERN` expects, for error messages."""
_ID = ENV_ID_PATTERN
_MAX_NAME = 200  # longest id or string value accepted
_MAX_LIST = 1000  # longest array accepted as a trajectory parameter
_MAX_SHOWN = 10  # problems spelled out in one message
_NESTING = 100  # arrays/tables nested deeper than this are reported by line

_short = reprlib.Repr()
_short.maxstring = 60
_short.maxother = 60
_short.maxlevel = 2
_short.maxlist = 6
_short.maxdict = 4

_T = TypeVar("_T")


class EnvSpecError(ValueError):
    """A malformed env spec file.

    Parameters
    ----------
    path : str or Path
        The spec file.
    problems : iterable of str
        One message per problem, each naming the key, the value and what was expected.
    """

    def __init__(self, path: str | Path, problems: Iterable[str]) -> None:
        self.path = str(path)
        self.problems = list(problems)
        shown = "; ".join(self.problems[:_MAX_SHOWN])
        more = len(self.problems) - _MAX_SHOWN
        super().__init__(f"{self.path}: {shown}" + (f"; and {more} more" if more > 0 else ""))

    def __reduce__(self) -> tuple[type, tuple[str, list[str]]]:
        return type(self), (self.path, self.problems)


class EnvSpecWarning(UserWarning):
    """A malformed env spec was skipped; the message names the file, the key and the problem."""


class EnvKeywordError(EnvSpecError):
    """Keyword arguments of ``gym.make`` (:func:`make_env`, :func:`make_vector_env`) that do not
    fit an env: unknown keywords (with near matches), values of the wrong type or out of range,
    or an ``axis``/``task`` object that contradicts the env's spec.

    Parameters
    ----------
    env_id : str
        The env the keywords were given to.
    problems : iterable of str
        One message per problem, each naming the keyword (``friction.fc``), the value and what
        was expected.
    """

    def __init__(self, env_id: str, problems: Iterable[str]) -> None:
        self.env_id = env_id
        super().__init__(f"{env_id} keywords", problems)

    def __reduce__(self) -> tuple[type, tuple[str, list[str]]]:
        return type(self), (self.env_id, self.problems)


@dataclass(frozen=True)
class EnvSpecFile:
    """A parsed env spec; ``data`` holds the file's ``axis`` and ``task`` tables as written."""

    id: str
    description: str
    axis: Axis
    task: TaskConfig
    path: str
    benchmark: bool
    fit_on: str
    data: Mapping[str, Any] = field(default_factory=dict, repr=False, compare=False)


# -- reading and checking one file -------------------------------------------------------------
def load_spec(path: str | Path, *, check_trajectories: bool = True) -> EnvSpecFile:
    """Parse and validate one TOML spec.

    Parameters
    ----------
    path : str or Path
        The spec file.
    check_trajectories : bool
        Also dry-run the trajectory generators (ids, parameters, axes, length; see the module
        docstring). ``fit_on`` is checked against the other specs by :func:`register_envs`.

    Returns
    -------
    EnvSpecFile

    Raises
    ------
    EnvSpecError
        Listing every problem found, each naming the key, the value and what was expected.
    """
    path = Path(path)
    data = _read(path)
    problems: list[str] = []
    _check_keys("", data, _TOP_KEYS, problems)
    env_id = data.get("id")
    if not (isinstance(env_id, str) and _ID.fullmatch(env_id)):
        problems.append(f"id={_show(env_id)}: expected a string {ENV_ID_FORM}"
                        if "id" in data else f"id: missing; expected {ENV_ID_FORM}")
    description = data.get("description", "")
    if not isinstance(description, str):
        problems.append(f"description={_show(description)}: expected a string")
    benchmark = data.get("benchmark", True)
    if not isinstance(benchmark, bool):
        problems.append(f"benchmark={_show(benchmark)}: expected true or false (a TOML boolean)")
    fit_on = data.get("fit_on", env_id)
    if "fit_on" in data and not (isinstance(fit_on, str) and _ID.fullmatch(fit_on)):
        problems.append(f"fit_on={_show(fit_on)}: expected an env id {ENV_ID_FORM}")
    axis = _check_axis(data.get("axis", {}), problems)
    task = _check_task(data.get("task", {}), axis, problems)
    if task is not None and axis is not None and check_trajectories:
        _probe_trajectories(task, axis, problems)
    if problems or axis is None or task is None:
        raise EnvSpecError(path, problems)
    return EnvSpecFile(cast(str, env_id), description, axis, task, str(path), benchmark,
                       cast(str, fit_on),
                       data={k: copy.deepcopy(data[k]) for k in ("axis", "task") if k in data})


def _read(path: Path) -> dict[str, Any]:
    """The TOML table of ``path``: a regular UTF-8 file of at most MAX_SPEC_BYTES."""
    try:
        if not stat.S_ISREG(path.stat().st_mode):
            raise EnvSpecError(path, ["not a regular file"])
        with path.open("rb") as fh:
            raw = fh.read(MAX_SPEC_BYTES + 1)
    except OSError as exc:
        raise EnvSpecError(path, [f"cannot read: {exc.strerror or exc}"]) from None
    if len(raw) > MAX_SPEC_BYTES:
        raise EnvSpecError(path, [f"file larger than {MAX_SPEC_BYTES} bytes (MAX_SPEC_BYTES)"])
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise EnvSpecError(path, [f"not UTF-8 text (byte {exc.start})"]) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise EnvSpecError(path, [f"invalid TOML: {exc}"]) from None
    except RecursionError:
        raise EnvSpecError(path, [f"invalid TOML: arrays or tables nested too deeply for the "
                                  f"parser{_deep_place(text)}"]) from None


def _deep_place(text: str) -> str:
    """Where brackets first nest deeper than _NESTING: ``" (line N, key 'k')"``."""
    depth = 0
    for n, line in enumerate(text.splitlines(), 1):
        for char in line:
            depth += (char in "[{") - (char in "]}")
            if depth > _NESTING:
                key = line.split("=", 1)[0].strip() if "=" in line else ""
                return f" (line {n}" + (f", key {_show(key)})" if key else ")")
    return ""


def _show(value: object) -> str:
    """A short repr for messages (long strings and deep structures abbreviated)."""
    return _short.repr(value)


def _key(section: str, key: object) -> str:
    name = key if isinstance(key, str) and len(key) <= 60 else _show(key)
    return f"{section}.{name}" if section else str(name)


def _check_keys(section: str, table: Mapping[str, Any], allowed: Iterable[str],
                problems: list[str]) -> bool:
    """Report each key of ``table`` not in ``allowed`` (with near matches); True if none."""
    allowed = list(allowed)
    unknown = [k for k in table if k not in allowed]
    for k in unknown:
        hint = did_you_mean(k, allowed) if len(k) <= _MAX_NAME else ""
        problems.append(f"{_key(section, k)}: unknown key{hint}; expected one of "
                        f"{', '.join(allowed)}")
    return not unknown


def _is_table(key: str, value: Any, problems: list[str]) -> bool:
    if isinstance(value, dict):
        return True
    problems.append(f"{key}={_show(value)}: expected a table")
    return False


def _is_real(value: Any) -> bool:
    """A TOML float, or a TOML integer (64-bit, so that ``float()`` of it cannot overflow)."""
    if isinstance(value, bool):
        return False
    return isinstance(value, float) or isinstance(value, int) and -2**63 <= value < 2**63


def _check_scalar(key: str, value: Any, default: Any, problems: list[str]) -> bool:
    """A TOML scalar of the kind of ``default`` (number, string or boolean), or an array of
    numbers where the default is a tuple (a linear law's coefficients)."""
    if isinstance(default, tuple):
        ok = (isinstance(value, (list, tuple)) and len(value) <= _MAX_LIST
              and all(_is_real(v) for v in value))
        if not ok:
            problems.append(f"{key}={_show(value)}: expected an array of numbers")
        return ok
    if isinstance(default, bool) or default is MISSING and isinstance(value, bool):
        ok, need = isinstance(value, bool), "true or false"
    elif isinstance(default, str) or default is MISSING and isinstance(value, str):
        ok, need = isinstance(value, str) and len(value) <= _MAX_NAME, "a string"
    else:
        ok, need = _is_real(value), "a number"
    if not ok:
        problems.append(f"{key}={_show(value)}: expected {need}")
    return ok


def _prefixed(section: str, exc: BaseException) -> str:
    """``exc``'s message with the section it concerns (``axis.controller.ts=...``)."""
    msg = str(exc)
    leaf = section.rsplit(".", 1)[-1]
    if msg.startswith(leaf + "."):
        msg = msg[len(leaf) + 1:]
    return f"{section}.{msg}" if re.match(r"[A-Za-z_]\w*=", msg) else f"{section}: {msg}"


def _check_section(section: str, value: Any, cls: object, build: Callable[..., _T],
                   problems: list[str]) -> _T | None:
    """Build one table with ``build(**value)`` after checking its keys and scalar types against
    the dataclass ``cls``; None (problems recorded) if anything is wrong."""
    if not _is_table(section, value, problems):
        return None
    ok = True
    if is_dataclass(cls):
        known = {f.name: f.default for f in fields(cls) if f.init}
        ok = _check_keys(section, value, known, problems)
        for k, v in value.items():
            if k in known:
                ok = _check_scalar(f"{section}.{k}", v, known[k], problems) and ok
    if not ok:
        return None
    try:
        return build(**value)
    except (TypeError, ValueError) as exc:
        problems.append(_prefixed(section, exc))
        return None


def _check_axis(value: Any, problems: list[str]) -> Axis | None:
    """The ``[axis]`` table, built as :meth:`Axis.from_dict` does."""
    if not _is_table("axis", value, problems):
        return None
    _check_keys("axis", value, _AXIS_KEYS, problems)
    controller = _check_section("axis.controller", value.get("controller", {}),
                                ControllerParams, ControllerParams, problems)
    mechanics = _check_section("axis.mechanics", value.get("mechanics", {}), MechanicsParams,
                               MechanicsParams, problems)
    effects = _check_section("axis.effects", value.get("effects", {}), Effects, Effects,
                             problems)
    friction = _check_friction(value.get("friction", {"id": "stribeck"}), problems)
    if controller is None or mechanics is None or effects is None or friction is None:
        return None
    try:
        return Axis(controller=controller, mechanics=mechanics, friction=friction,
                    effects=effects)
    except ValueError as exc:  # an unstable loop: the message starts with "controller.kp=..."
        problems.append(f"axis.{exc}")
        return None


def _check_friction(value: Any, problems: list[str]) -> FrictionModel | None:
    if not _is_table("axis.friction", value, problems):
        return None
    params = dict(value)
    fid = params.pop("id", "stribeck")
    ids = friction_registry.ids()
    if not isinstance(fid, str) or fid not in ids:
        hint = did_you_mean(fid, ids) if isinstance(fid, str) and len(fid) <= _MAX_NAME else ""
        problems.append(f"axis.friction.id={_show(fid)}: unknown friction model{hint}; "
                        f"expected one of {', '.join(ids)}")
        return None
    cls = friction_registry.spec(fid).load()
    return _check_section("axis.friction", params, cls,
                          lambda **kw: friction_registry.make(fid, **kw), problems)


def _check_task(value: Any, axis: Axis | None, problems: list[str]) -> TaskConfig | None:
    """The ``[task]`` table, built as :meth:`TaskConfig.from_dict` does."""
    if not _is_table("task", value, problems):
        return None
    known = {f.name: f.default for f in fields(TaskConfig)}
    ok = _check_keys("task", value, known, problems)
    kw: dict[str, Any] = {}
    for name in ("action", "action_scale"):
        if name in value:
            ok = _check_scalar(f"task.{name}", value[name], known[name], problems) and ok
            kw[name] = value[name]
    if "trajectories" in value:
        kw["trajectories"] = _check_trajectories(value["trajectories"], problems)
    for name, cls in (("observation", ObservationConfig), ("reward", RewardConfig)):
        if name in value:
            kw[name] = _check_section(f"task.{name}", value[name], cls, cls, problems)
    if "randomize" in value:
        kw["randomize"] = _check_randomize(value["randomize"], axis, problems)
    if not ok or any(v is None for v in kw.values()):
        return None
    try:
        return TaskConfig(**kw)
    except (TypeError, ValueError) as exc:
        problems.append(_prefixed("task", exc))
        return None


def _check_trajectories(value: Any, problems: list[str]) -> tuple[TrajectoryChoice, ...] | None:
    """Shape and value types of ``task.trajectories`` (ids and parameters: the dry run)."""
    key = "task.trajectories"
    if not isinstance(value, list):
        hint = f" (write {json.dumps([value])})" if isinstance(value, str) and len(value) < 60 \
            else ""
        problems.append(f"{key}={_show(value)}: expected an array of trajectory ids or tables "
                        f"with an 'id'{hint}")
        return None
    if not value or len(value) > MAX_TRAJECTORIES:
        problems.append(f"{key}: {len(value)} entries; expected 1 to {MAX_TRAJECTORIES} "
                        "(MAX_TRAJECTORIES)")
        return None
    out: list[TrajectoryChoice] = []
    n_problems = len(problems)
    for i, item in enumerate(value):
        k = f"{key}[{i}]"
        if isinstance(item, str):
            tid, params = item, {}
        elif isinstance(item, dict):
            params = dict(item)
            tid = params.pop("id", None)
        else:
            problems.append(f"{k}={_show(item)}: expected a trajectory id or a table with an "
                            "'id'")
            continue
        if not isinstance(tid, str) or not tid or len(tid) > _MAX_NAME:
            problems.append(f"{k}.id={_show(tid)}: expected a trajectory id string")
            continue
        for p, v in params.items():
            if p == "ts":
                problems.append(f"{k}.ts: not settable here; the sample time is "
                                "axis.controller.ts")
            elif not (_is_real(v) or isinstance(v, bool)
                      or isinstance(v, str) and len(v) <= _MAX_NAME
                      or isinstance(v, list) and len(v) <= _MAX_LIST and all(map(_is_real, v))):
                problems.append(f"{_key(k, p)}={_show(v)}: expected a number, a string, true or "
                                f"false, or an array of at most {_MAX_LIST} numbers")
        out.append(TrajectoryChoice(tid, params))
    return tuple(out) if len(problems) == n_problems else None


class _Corner:
    """Stands in for the generator of :meth:`Randomization.sample`: every draw is the low (or
    the high) end of its range."""

    def __init__(self, high: bool) -> None:
        self.high = high

    def uniform(self, low: float, high: float) -> float:
        return high if self.high else low


def _check_randomize(value: Any, axis: Axis | None, problems: list[str]) -> Randomization | None:
    """``task.randomize``: known friction parameters, ``[low, high]`` ranges, and a valid model
    at both ends."""
    key = "task.randomize"
    if not _is_table(key, value, problems):
        return None
    n_problems = len(problems)
    allowed = None
    if axis is not None:
        allowed = [*(k for k in axis.friction.to_dict() if k != "id"), "fs_ratio", "scale"]
        _check_keys(key, value, allowed, problems)
    ranges: dict[str, tuple[float, float]] = {}
    for k, rng in value.items():
        if not (isinstance(rng, list) and len(rng) == 2 and all(map(_is_real, rng))
                and all(map(math.isfinite, rng)) and rng[0] <= rng[1]):
            problems.append(f"{_key(key, k)}={_show(rng)}: expected [low, high], two finite "
                            "numbers with low <= high")
        elif allowed is None or k in allowed:
            ranges[k] = (rng[0], rng[1])
    randomization = Randomization(ranges)
    if axis is not None:
        for end in ("low", "high"):
            try:
                randomization.sample(axis, cast(np.random.Generator, _Corner(end == "high")))
            except (TypeError, ValueError) as exc:
                problems.append(f"{key}: the friction model at the {end} ends of the ranges is "
                                f"invalid: {exc}")
                break
    return randomization if len(problems) == n_problems else None


def _parameter_names(factory: Callable[..., Any]) -> list[str] | None:
    """Keyword parameters of a trajectory generator (None if it takes ``**kwargs``)."""
    try:
        sig = inspect.signature(factory)
    except (TypeError, ValueError):
        return None
    if any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values()):
        return None
    return [n for n, p in sig.parameters.items()
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and n != "ts"]


def _probe_trajectories(task: TaskConfig, axis: Axis, problems: list[str]) -> None:
    """Dry-run every trajectory generator at PROBE_TS: ids, parameters, axes and length."""
    ts = axis.controller.ts
    ids = trajectory_registry.ids()
    total, n_axes = 0, None
    for i, choice in enumerate(task.trajectories):
        k = f"task.trajectories[{i}]"
        if choice.id not in ids:
            problems.append(f"{k}: unknown trajectory id {_show(choice.id)}"
                            f"{did_you_mean(choice.id, ids)}; expected one of {', '.join(ids)}")
            continue
        try:
            names = _parameter_names(trajectory_registry.spec(choice.id).load())
        except ImportError as exc:
            problems.append(f"{k}: trajectory {choice.id!r} cannot be loaded: {exc}")
            continue
        unknown = [p for p in choice.params if names is not None and p not in names]
        for p in unknown:
            problems.append(f"{_key(k, p)}: unknown parameter of trajectory {choice.id!r}"
                            f"{did_you_mean(p, names or ())}; expected one of "
                            f"{', '.join(names or ())}")
        duration = choice.params.get("duration")
        if isinstance(duration, (int, float)) and duration > MAX_REFERENCE_SAMPLES * ts:
            problems.append(f"{k}.duration={duration!r}: expected at most "
                            f"{MAX_REFERENCE_SAMPLES * ts:g} s ({MAX_REFERENCE_SAMPLES} samples "
                            f"at ts={ts:g} s: MAX_REFERENCE_SAMPLES)")
            continue
        if unknown:
            continue
        try:
            ref = reference_for(choice, PROBE_TS, np.random.default_rng(0))
        except Exception as exc:  # noqa: BLE001 - any failure of a generator on these parameters
            problems.append(_prefixed(k, exc))  # is a problem of this spec, reported as such
            continue
        if n_axes is not None and ref.n_axes != n_axes:
            problems.append(f"{k}: a {ref.n_axes}-axis trajectory in a set of {n_axes}-axis "
                            "trajectories; expected one number of axes")
        n_axes = ref.n_axes if n_axes is None else n_axes
        total += math.ceil(ref.duration / ts) + 1
    if total > MAX_REFERENCE_SAMPLES:
        problems.append(f"task.trajectories: {total} reference samples at ts={ts:g} s; expected "
                        f"at most {MAX_REFERENCE_SAMPLES} (MAX_REFERENCE_SAMPLES)")


# -- the set of spec files ---------------------------------------------------------------------
def _shipped_files() -> list[Path]:
    shipped = resources.files("fricbench.gym").joinpath("specs")
    return sorted(Path(str(shipped)).glob("*.toml"))


_reported_folders: set[str] = set()  # FRICBENCH_ENV_PATH entries already warned about


def _user_files() -> list[Path]:
    """The ``*.toml`` files of the ``FRICBENCH_ENV_PATH`` folders; a folder that is missing
    (or not a folder) is skipped, reported once with an :class:`EnvSpecWarning`."""
    files: list[Path] = []
    for folder in filter(None, os.environ.get("FRICBENCH_ENV_PATH", "").split(os.pathsep)):
        if not Path(folder).is_dir():
            what = "is not a folder" if Path(folder).exists() else "does not exist"
            if folder not in _reported_folders:
                _reported_folders.add(folder)
                warnings.warn(f"FRICBENCH_ENV_PATH: {folder} {what}; no env specs read from "
                              "it", EnvSpecWarning, stacklevel=2)
            continue
        files.extend(sorted(Path(folder).glob("*.toml")))
    return files


def spec_files() -> list[Path]:
    """The shipped specs (``fricbench/gym/specs`` -> the repository's ``envs/``) and any in
    ``FRICBENCH_ENV_PATH`` (``os.pathsep``-separated folders), in that order."""
    return _shipped_files() + _user_files()


def _load_all(paths: Iterable[Path], known: Mapping[str, EnvSpecFile],
              check_trajectories: Callable[[Path], bool],
              ) -> tuple[list[EnvSpecFile], list[EnvSpecError]]:
    """Load ``paths`` in order next to the ``known`` specs: the good specs and the problems.

    An id defined earlier (shipped specs come first) wins over a later duplicate; a ``fit_on``
    must name a known or good spec.
    """
    good: dict[str, EnvSpecFile] = {}
    problems: list[EnvSpecError] = []
    for path in paths:
        try:
            spec = load_spec(path, check_trajectories=check_trajectories(path))
        except EnvSpecError as exc:
            problems.append(exc)
            continue
        except Exception as exc:  # noqa: BLE001 - one spec file must never break the others
            problems.append(EnvSpecError(path, [f"unexpected {type(exc).__name__}: {exc}"]))
            continue
        other = known.get(spec.id) or good.get(spec.id)
        if other is not None:
            if other.path != spec.path:
                problems.append(EnvSpecError(path, [f"id={spec.id!r}: already defined by "
                                                    f"{other.path}"]))
            continue
        good[spec.id] = spec
    dropped = True
    while dropped:  # a spec trained on a dropped one is dropped too
        dropped = False
        ids = [*known, *good]
        for spec in list(good.values()):
            if spec.fit_on not in ids:
                problems.append(EnvSpecError(spec.path, [
                    f"fit_on={spec.fit_on!r}: not a registered env id"
                    f"{did_you_mean(spec.fit_on, ids)}"]))
                del good[spec.id]
                dropped = True
    return list(good.values()), problems


_ENTRY_POINT = "fricbench.gym.specs:make_env"
_VECTOR_ENTRY_POINT = "fricbench.gym.specs:make_vector_env"


class EnvRegistry(Registry[gym.Env]):
    """The env ids, each registered with its parsed spec (:attr:`RegistryEntry.data`) and with
    Gymnasium.

    ``make(id, **overrides)`` is :func:`make_env`; :func:`get_spec` gives an id's
    :class:`EnvSpecFile`. At the first look-up the registry reads the spec files (the shipped
    ones, then those on ``FRICBENCH_ENV_PATH``), then the plug-ins of its entry-point group
    (``fricbench.envs``); :func:`register_envs` reads the files added since.

    A plug-in's entry point names a spec file (a path, as ``str`` or :class:`os.PathLike`), a
    parsed :class:`EnvSpecFile`, or, like every registry's plug-ins, a callable taking the
    registry (which calls :meth:`register_spec`). A plug-in that fails, or a malformed spec it
    gives, is skipped with an :class:`EnvSpecWarning`, as a malformed spec file is: the import
    of :mod:`fricbench` registers the envs and must not fail for one of them.

    Parameters
    ----------
    kind : str
        Human name of what is registered, used in messages.
    group : str
        Python entry-point group scanned once for plug-ins.
    """

    def __init__(self, kind: str = "env", group: str = "fricbench.envs") -> None:
        super().__init__(kind, group)
        self._files_read: set[str] = set()  # spec files already read (registered or skipped)

    def register(self, id: str, entry_point: str | Callable[..., Any], *,
                 kwargs: dict[str, Any] | None = None, description: str = "",
                 data: Any = None) -> None:
        """Register ``id`` with its parsed spec ``data`` (and with Gymnasium).

        :meth:`register_spec` is the way to add an env; this method takes what it passes.

        Raises
        ------
        TypeError
            If ``data`` is not an :class:`EnvSpecFile` of ``id``.
        EnvSpecError
            If the spec's ``fit_on`` is not a registered env id.
        DuplicateIdError
            If ``id`` is registered already.
        """
        if not (isinstance(data, EnvSpecFile) and data.id == id):
            raise TypeError(f"data={_show(data)}: expected the EnvSpecFile of {id!r}; add an "
                            "env with register_spec(a spec file's path or an EnvSpecFile)")
        if data.fit_on != id and data.fit_on not in self._entries:
            raise EnvSpecError(data.path, [f"fit_on={data.fit_on!r}: not a registered env id"
                                           f"{did_you_mean(data.fit_on, self._entries)}"])
        super().register(id, entry_point, kwargs=kwargs, description=description, data=data)
        single = all(t.id != "circle" for t in data.task.trajectories)
        gym.register(id=id, entry_point=_ENTRY_POINT,
                     vector_entry_point=_VECTOR_ENTRY_POINT if single else None,
                     kwargs={"spec_id": id})

    def register_spec(self, spec: str | os.PathLike[str] | EnvSpecFile) -> str:
        """Register an env from a spec file or a parsed spec; return its id.

        A spec file is read with every check of :func:`load_spec`; the trajectories of a
        parsed spec are dry-run as a file's are. Registering the same file again does nothing.

        Parameters
        ----------
        spec : str, os.PathLike or EnvSpecFile
            A TOML spec file (the format of ``envs/``), or its :func:`load_spec`.

        Returns
        -------
        str
            The env id.

        Raises
        ------
        EnvSpecError
            Listing the problems of the spec: malformed, an id already defined by another
            file, a ``fit_on`` that is not registered.
        TypeError
            If ``spec`` is neither a path nor an :class:`EnvSpecFile`.
        """
        if isinstance(spec, EnvSpecFile):
            problems: list[str] = []
            _probe_trajectories(spec.task, spec.axis, problems)
            if problems:
                raise EnvSpecError(spec.path, problems)
        elif isinstance(spec, (str, os.PathLike)):
            spec = load_spec(Path(spec))
        else:
            raise TypeError(f"spec={_show(spec)} ({type(spec).__name__}): expected a spec "
                            "file's path or an EnvSpecFile")
        other = self._entries.get(spec.id)
        if other is not None:
            if other.data.path == spec.path:
                return spec.id
            raise EnvSpecError(spec.path, [f"id={spec.id!r}: already defined by "
                                           f"{other.data.path}"])
        self.register(spec.id, _ENTRY_POINT, kwargs={"spec_id": spec.id},
                      description=spec.description, data=spec)
        return spec.id

    def unregister(self, id: str) -> None:
        """Remove ``id``, from Gymnasium's registry too."""
        super().unregister(id)
        gym.registry.pop(id, None)

    def read_files(self) -> None:
        """Register the spec files not read yet (idempotent).

        A malformed one (or one whose id is already registered) is skipped with an
        :class:`EnvSpecWarning` naming the file, the key and the problem.
        """
        new = [p for p in spec_files() if str(p) not in self._files_read]
        if not new:
            return
        shipped = {str(p) for p in _shipped_files()}
        known = {i: e.data for i, e in self._entries.items()}
        specs, problems = _load_all(new, known, lambda p: str(p) not in shipped)
        self._files_read.update(str(p) for p in new)
        for exc in problems:
            _warn_skipped(exc)
        while specs:  # each after the env it is fit on (_load_all kept only those it finds)
            ready = [s for s in specs if s.fit_on == s.id or s.fit_on in self._entries]
            for spec in ready:
                self.register(spec.id, _ENTRY_POINT, kwargs={"spec_id": spec.id},
                              description=spec.description, data=spec)
            if not ready:  # cannot happen: every fit_on was found
                raise RuntimeError(f"env specs fit on unregistered envs: {specs}")
            specs = [s for s in specs if all(s.id != r.id for r in ready)]

    def _ensure_plugins(self) -> None:
        if not self._plugins_loaded:  # the files first: a plug-in's spec may be fit on them
            self.read_files()
        super()._ensure_plugins()

    def _load_plugin(self, ep: importlib.metadata.EntryPoint) -> None:
        try:
            obj = ep.load()
            if isinstance(obj, (str, os.PathLike, EnvSpecFile)):
                self.register_spec(obj)
            else:
                super()._load_plugin(ep)
        except EnvSpecError as exc:
            _warn_skipped(exc)
        except Exception as exc:  # noqa: BLE001 - one plug-in must never break the other envs
            warnings.warn(f"entry point {ep.name!r} = {ep.value!r} in group {self.group!r}: "
                          f"{type(exc).__name__}: {exc} (the env specs it gives are skipped)",
                          EnvSpecWarning, stacklevel=2)


def _warn_skipped(exc: EnvSpecError) -> None:
    warnings.warn(f"{exc} (this env spec is skipped; 'fricbench list --check' reports "
                  "every problem)", EnvSpecWarning, stacklevel=3)


env_registry = EnvRegistry()
"""Every env id with its parsed spec; third-party packages add specs through the
``fricbench.envs`` entry-point group."""


def register_envs() -> list[str]:
    """Register every spec with Gymnasium (idempotent); return the ids.

    Spec files are read once: the shipped ones, those on ``FRICBENCH_ENV_PATH``, and at the
    first call the plug-ins' specs (:class:`EnvRegistry`). A malformed one (or one whose id is
    already registered) is skipped with an :class:`EnvSpecWarning` naming the file, the key
    and the problem.
    """
    env_registry.read_files()
    return env_registry.ids()


def check_specs() -> list[EnvSpecError]:
    """Validate every spec file with every check, the trajectory dry run included.

    Registers nothing; this is ``fricbench list --check``.

    Returns
    -------
    list of EnvSpecError
        One per malformed file (empty when every spec is good).
    """
    return _load_all(spec_files(), {}, lambda p: True)[1]


def env_ids(benchmark_only: bool = False) -> list[str]:
    """Registered fricbench env ids (optionally only those the benchmark runs)."""
    register_envs()
    return [i for i in env_registry.ids()
            if get_spec(i).benchmark or not benchmark_only]


def get_spec(spec_id: str) -> EnvSpecFile:
    """The parsed spec of a registered id (with near-match suggestions when unknown)."""
    register_envs()
    spec: EnvSpecFile = env_registry.spec(spec_id).data
    return spec


# -- keyword overrides of gym.make --------------------------------------------------------------
OVERRIDE_KEYWORDS = ("controller", "mechanics", "friction", "effects", "trajectories", "action",
                     "action_scale", "observation", "reward", "randomize")
"""Keywords of ``gym.make`` (:func:`make_env`, :func:`make_vector_env`) merged onto an env's spec,
besides ``axis``, ``task`` and the parameters of these tables."""

# keyword -> (the table it overrides in the spec, the dataclass of that table)
_TABLES: dict[str, tuple[str, type]] = {
    "controller": ("axis", ControllerParams), "mechanics": ("axis", MechanicsParams),
    "effects": ("axis", Effects), "observation": ("task", ObservationConfig),
    "reward": ("task", RewardConfig)}
_EXAMPLES = {"controller": "{'kp': 200.0}", "mechanics": "{'mass': 500.0}",
             "effects": "{'noise_std': 1e-7}", "observation": "{'preview': 3}",
             "reward": "{'action_weight': 0.1}", "randomize": "{'fc': [300.0, 400.0]}",
             "friction": "'lugre' or friction={'fc': 400.0}"}


def _plain(value: Any) -> Any:
    """``value`` as the TOML reader would give it: numpy scalars as Python numbers, tuples as
    lists, mappings as dicts, a :class:`TrajectoryChoice` as its table; anything else as is
    (the spec checks then name it)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, TrajectoryChoice):
        return value.id if not value.params else {"id": value.id, **_plain(value.params)}
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _init_fields(cls: object) -> list[str]:
    return [f.name for f in fields(cls) if f.init] if is_dataclass(cls) else []


def _differences(written: Mapping[str, Any], spec_full: Mapping[str, Any],
                 given_full: Mapping[str, Any], prefix: str = "") -> list[str]:
    """``key=given (the spec: value)`` for each key the spec file writes (``written``) whose
    value in the spec's full table (``spec_full``) the given object's full table
    (``given_full``) does not have. A friction table always compares the model id."""
    out = []
    keys = list(written)
    if prefix == "friction." and "id" not in keys:
        keys.insert(0, "id")  # a friction table without an id is Stribeck's
    for k in keys:
        w, mine, theirs = written.get(k), spec_full.get(k), given_full.get(k)
        if isinstance(w, dict) and isinstance(mine, dict):
            out += _differences(w, mine, theirs if isinstance(theirs, dict) else {},
                                f"{prefix}{k}.")
        elif mine != theirs:
            out.append(f"{prefix}{k}={_show(theirs)} (the spec: {_show(mine)})")
    return out


def _check_objects(spec: EnvSpecFile, overrides: Mapping[str, Any], problems: list[str]) -> None:
    """``axis`` and ``task`` given to ``gym.make`` must be an :class:`Axis` and a
    :class:`TaskConfig` (``None`` would silently give the default axis; ``TypeError``), and
    agree with every setting the spec file writes (problems recorded)."""
    for name, cls in (("axis", Axis), ("task", TaskConfig)):
        if name not in overrides:
            continue
        value = overrides[name]
        if not isinstance(value, cls):
            raise TypeError(f"{name}={_show(value)} ({type(value).__name__}): expected "
                            f"{'an' if name == 'axis' else 'a'} {cls.__name__}, or leave "
                            f"{name} out for the one of {spec.id}")
        mine = spec.axis.to_dict() if name == "axis" else spec.task.to_dict()
        diff = _differences(spec.data.get(name, {}), mine, value.to_dict())
        if diff:
            hint = ("friction={'fc': 400.0}, effects={'noise_std': 1e-7}" if name == "axis"
                    else "trajectories=['s_curve'], reward={'action_weight': 0.1}")
            problems.append(
                f"{name}={cls.__name__}(...) contradicts what {spec.id} sets: "
                f"{', '.join(diff)}; give only what you change, as keywords merged onto the "
                f"spec ({hint}), or build ServoAxisEnv({name}=...) for "
                f"{'an axis' if name == 'axis' else 'a task'} of your own")


def _user_key(problem: str) -> str:
    """A spec-file message in keyword terms: ``axis.friction.fc=...`` -> ``friction.fc=...``."""
    problem = re.sub(r"^(axis|task)\.", "", problem)
    drawn = re.match(r"randomize\.(\w+): unknown key", problem)
    if drawn:  # the spec's randomisation of a parameter the new friction model does not have
        problem += f" (randomize={{{drawn.group(1)!r}: None}} stops drawing it)"
    return problem


def resolve_overrides(spec_id: str, **overrides: Any) -> tuple[Axis, TaskConfig]:
    """The axis and task of a registered env with keyword overrides merged onto its spec.

    This is what :func:`make_env` and :func:`make_vector_env` build their env from; see
    :func:`make_env` for the keywords.

    Parameters
    ----------
    spec_id : str
        A registered env id.
    **overrides
        The keywords given to ``gym.make``.

    Returns
    -------
    axis : Axis
    task : TaskConfig

    Raises
    ------
    EnvKeywordError
        Listing every problem: unknown keywords (with near matches), values of the wrong type
        or out of range (the checks of the spec files), an ``axis``/``task`` that contradicts
        the spec.
    TypeError
        If ``axis`` or ``task`` is not an :class:`Axis` or a :class:`TaskConfig`.
    UnknownIdError
        If ``spec_id`` is not registered.
    """
    spec = get_spec(spec_id)
    problems: list[str] = []
    _check_objects(spec, overrides, problems)
    if problems:
        raise EnvKeywordError(spec.id, problems)
    base_axis = overrides.get("axis", spec.axis)
    base_task = overrides.get("task", spec.task)
    kw = {k: _plain(v) for k, v in overrides.items() if k not in ("axis", "task")}
    if not kw:
        return base_axis, base_task
    axis_t, task_t = base_axis.to_dict(), base_task.to_dict()
    tables: dict[str, dict[str, Any]] = {}  # keyword -> its table of overrides
    for name, value in kw.items():
        if name == "friction" and isinstance(value, str):
            tables[name] = {"id": value}
        elif name in (*_TABLES, "friction", "randomize"):
            if isinstance(value, dict):
                tables[name] = dict(value)
            else:
                what = ("a friction model id or a dict of its parameters" if name == "friction"
                        else "a dict of [low, high] ranges" if name == "randomize"
                        else f"a dict of {_TABLES[name][1].__name__} fields")
                problems.append(f"{name}={_show(value)} ({type(value).__name__}): expected "
                                f"{what}, such as {name}={_EXAMPLES[name]}")
    # the friction model the env ends up with: a new id keeps the parameters it shares
    friction = dict(axis_t["friction"])
    new_id = tables.get("friction", {}).get("id", friction["id"])
    new_id = "stribeck" if new_id is None else new_id  # as in a spec's friction table
    new_cls = None
    if isinstance(new_id, str) and new_id in friction_registry.ids():
        new_cls = friction_registry.spec(new_id).load()
        if new_id != friction["id"]:
            keep = _init_fields(new_cls)
            friction = {"id": new_id, **{k: v for k, v in friction.items() if k in keep}}
    else:
        _check_friction({"id": new_id}, problems)  # names it, with near matches
    # parameters given on their own (fc=400.0) go to the one table that has them
    leaves = {name: _init_fields(cls) for name, (_, cls) in _TABLES.items()}
    leaves["friction"] = [f for f in _init_fields(new_cls) if f != "id"]
    for name, value in kw.items():
        if name in OVERRIDE_KEYWORDS:
            continue
        owners = [t for t, names in leaves.items() if name in names]
        if len(owners) == 1:
            table = tables.setdefault(owners[0], {})
            if name in table:
                problems.append(f"{name}={_show(value)} and {owners[0]}={{{name!r}: "
                                f"{_show(table[name])}}} both set {owners[0]}.{name}; give it "
                                "once")
            table[name] = value
        elif owners:
            problems.append(f"{name}: a key of {' and '.join(owners)}; give it in one of them "
                            f"({', '.join(f'{o}={{{name!r}: ...}}' for o in owners)})")
        elif new_cls is not None:  # (with an unknown friction id, reported, it may be one of
            # the parameters of the model meant)
            names = [*OVERRIDE_KEYWORDS, *(n for ns in leaves.values() for n in ns)]
            problems.append(f"{name}: unknown keyword{did_you_mean(name, names)}; expected "
                            f"axis, task, {', '.join(OVERRIDE_KEYWORDS)}, or a key of one of "
                            f"these tables (fc=400.0 is friction={{'fc': 400.0}})")
    if problems:
        raise EnvKeywordError(spec.id, [_user_key(p) for p in problems])
    # merge: a table key by key (None: back to the default), anything else replaced
    for name, table in tables.items():
        in_axis = name == "friction" or name in _TABLES and _TABLES[name][0] == "axis"
        target = axis_t if in_axis else task_t
        merged = friction if name == "friction" else dict(target[name])
        for k, v in table.items():
            if v is None:
                merged.pop(k, None)
            else:
                merged[k] = copy.deepcopy(v)
        target[name] = merged
    axis_t["friction"] = friction
    for name in ("trajectories", "action", "action_scale"):
        if name in kw:
            task_t[name] = copy.deepcopy(kw[name])
    axis = _check_axis(axis_t, problems)
    task = _check_task(task_t, axis, problems)
    if axis is not None and task is not None and (
            "trajectories" in kw or axis.controller.ts != base_axis.controller.ts):
        _probe_trajectories(task, axis, problems)
    if problems or axis is None or task is None:
        raise EnvKeywordError(spec.id, [_user_key(p) for p in problems])
    return axis, task


def make_env(spec_id: str, render_mode: str | None = None, **overrides: Any) -> gym.Env:
    """Entry point of every registered id: the scalar env of ``spec_id``.

    ``gym.make(spec_id, **overrides)`` lands here. Every keyword is merged onto the env's
    spec and the result is checked as a spec file is (the same checks, the same messages), so
    ``gym.make("fricbench/PaperAxisShifted-v0", effects={"noise_std": 1e-7})`` keeps the env's
    +30 % friction.

    Parameters
    ----------
    spec_id : str
        A registered env id (``fricbench/PaperAxis-v0``).
    render_mode : {"rgb_array", "human"}, optional
    **overrides
        ``controller``, ``mechanics``, ``effects``, ``observation``, ``reward`` : dict
            Merged key by key onto that table of the spec (``controller={"kp": 200.0}``).
        ``friction`` : str or dict
            A friction model id (``"lugre"``) or a dict of parameters merged onto the spec's
            friction table (``{"fc": 400.0}``, or ``{"id": "lugre", "sigma0": 1e8}``). A new
            model keeps the parameters it shares with the spec's (``fc``, ``fs``, ``vs`` from
            Stribeck to LuGre); its others take their defaults.
        ``trajectories`` : list
            Replaces the trajectory set: ids or ``{"id": ..., **params}`` dicts.
        ``action`` : {"force", "offset"}; ``action_scale`` : float
        ``randomize`` : dict
            ``{parameter: [low, high]}`` merged onto the spec's friction randomisation.
        ``fc=400.0``, ``kp=200.0``, ... : a key of one of these tables on its own, when exactly
            one table has it (``error_scale`` is in ``observation`` and ``reward``: give the
            table).
        In a dict, or on its own, a key given as ``None`` takes the table's default instead
        of the spec's (``randomize={"fc": None}`` stops drawing ``fc``).
        ``axis`` : Axis; ``task`` : TaskConfig
            Used in place of the spec's, provided they agree with every setting the spec file
            writes (otherwise :class:`EnvKeywordError` lists the differences: give the changes
            as the keywords above instead); the other keywords are merged onto them.

    Returns
    -------
    ServoAxisEnv

    Raises
    ------
    EnvKeywordError
        A ``ValueError`` listing every problem with the keywords: unknown keywords (with near
        matches), wrong types or values, an ``axis``/``task`` that contradicts the spec.
    TypeError
        ``axis`` or ``task`` that is not an :class:`Axis` or a :class:`TaskConfig`.
    """
    from fricbench.gym.env import ServoAxisEnv

    axis, task = resolve_overrides(spec_id, **overrides)
    return ServoAxisEnv(axis=axis, task=task, render_mode=render_mode)


# keywords of ServoAxisVectorEnv itself (every other keyword is merged onto the spec)
_VECTOR_ARGS = ("reference_pool", "seed", "render_mode", "autoreset_mode")


def make_vector_env(spec_id: str, num_envs: int = 1, **kwargs: Any) -> gym.vector.VectorEnv:
    """Vector entry point: the native :class:`ServoAxisVectorEnv` of ``spec_id``.

    ``gym.make_vec(spec_id, num_envs, vectorization_mode="vector_entry_point", **kwargs)``
    lands here.

    Parameters
    ----------
    spec_id : str
        A registered single-axis env id.
    num_envs : int
        Number of sub-envs.
    **kwargs
        ``reference_pool``, ``seed``, ``render_mode`` and ``autoreset_mode`` of
        :class:`ServoAxisVectorEnv`; every
        other keyword is merged onto the env's spec as in :func:`make_env` (``friction``,
        ``effects``, ``fc``, ``trajectories``, ``axis``, ...).

    Raises
    ------
    EnvKeywordError
        As :func:`make_env`.
    """
    from fricbench.gym.vector import ServoAxisVectorEnv

    args = {k: kwargs.pop(k) for k in _VECTOR_ARGS if k in kwargs}
    axis, task = resolve_overrides(spec_id, **kwargs)
    return ServoAxisVectorEnv(num_envs=num_envs, axis=axis, task=task, **args)
