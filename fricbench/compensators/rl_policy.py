"""Safe policy files for the RL compensators: weights plus a JSON, never a pickle.

A policy is two files side by side::

    rl-sac.json   format, algorithm, dims, net_arch, activation, output squashing,
                  observation normalisation, how it was trained (command, seed, steps, ...)
    rl-sac.pt     ``torch.save(state_dict)`` of :class:`PolicyMLP` (tensors only)

The weights are loaded with ``torch.load(path, weights_only=True)``, which cannot execute
code (unlike a stable-baselines3 zip, whose ``data`` entry is a cloudpickle); nothing the JSON
names is imported. Sizes are checked before anything is allocated: the JSON is at most
:data:`~fricbench._safe_load.MAX_JSON_BYTES`, the weights file and the network the JSON
declares at most :data:`~fricbench._safe_load.MAX_MODEL_BYTES`. Any problem (missing or
oversized file, bad JSON, wrong field, tensors of another dtype or shape than the declared
network) raises :class:`~fricbench.compensators.base.CompensatorError` naming the file and
the field.

Inference runs the deterministic action of the trained agent::

    a = squash(W_n act(... act(W_1 (obs - mean) / std + b_1) ...) + b_n)

with ``squash = tanh`` for SAC (its squashed Gaussian's mean) and ``clip(-1, 1)`` for PPO
(stable-baselines3 clips the Gaussian mean to the action space), as plain numpy products
whose result for one observation does not depend on the others stepped with it (a batch of
episodes acts exactly as each episode alone).
"""

from __future__ import annotations

import json
from collections.abc import Collection, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from fricbench._safe_load import (
    MAX_JSON_BYTES,
    MAX_MODEL_BYTES,
    UnsafeFileError,
    load_tensors,
    parse_json,
    read_file,
)
from fricbench.compensators.base import CompensatorError

__all__ = ["PolicySpec", "PolicyMLP", "NumpyPolicy", "save_policy", "load_policy",
           "FORMAT_VERSION"]

FORMAT_VERSION = 1
_ACTIVATIONS: dict[str, type[nn.Module]] = {"relu": nn.ReLU, "tanh": nn.Tanh}
_SQUASH = ("tanh", "clip")


@dataclass(frozen=True)
class PolicySpec:
    """The JSON half of a policy file.

    Parameters
    ----------
    algo : str
        ``"sac"`` or ``"ppo"``.
    obs_dim : int
        Observation features of one axis.
    act_dim : int
        Action entries of one axis (1).
    net_arch : sequence of int
        Hidden layer widths.
    activation : {"relu", "tanh"}
        Hidden activation.
    squash : {"tanh", "clip"}
        Output map to [-1, 1].
    action_mode : {"force", "offset"}
        The env action the policy was trained for.
    action_scale : float
        The env's ``action_scale`` in training (N or m per unit).
    obs_mean, obs_std : list of float or None
        Observation normalisation (``None``: none).
    env_id : str
        Training env.
    training : dict
        ``command``, ``seed``, ``steps``, ``seconds``, library versions, hyperparameters.
    weights : str
        File name of the weights, relative to the JSON.
    """

    algo: str
    obs_dim: int
    act_dim: int
    net_arch: tuple[int, ...]
    activation: str
    squash: str
    action_mode: str
    action_scale: float
    env_id: str
    weights: str
    obs_mean: tuple[float, ...] | None = None
    obs_std: tuple[float, ...] | None = None
    training: Mapping[str, Any] = field(default_factory=dict)
    format_version: int = FORMAT_VERSION

    def to_json(self) -> str:
        """JSON text (keys sorted, indented)."""
        d = asdict(self)
        d["net_arch"] = list(self.net_arch)
        d["training"] = dict(self.training)
        return json.dumps(d, indent=2, sort_keys=True) + "\n"

    @classmethod
    def from_dict(cls, data: Any, path: str) -> PolicySpec:
        """Validate a parsed JSON object; errors name ``path`` and the field."""
        if not isinstance(data, dict):
            raise CompensatorError(f"{path}: expected a JSON object, got {type(data).__name__}")
        version = data.get("format_version")
        if version != FORMAT_VERSION:
            raise CompensatorError(f"{path}: format_version={version!r}; this fricbench reads "
                                   f"version {FORMAT_VERSION}")
        known = set(cls.__dataclass_fields__)
        unknown = set(data) - known
        if unknown:
            raise CompensatorError(f"{path}: unknown fields {sorted(unknown)}")
        missing = {"algo", "obs_dim", "act_dim", "net_arch", "activation", "squash",
                   "action_mode", "action_scale", "env_id", "weights"} - set(data)
        if missing:
            raise CompensatorError(f"{path}: missing fields {sorted(missing)}")

        def need(ok: bool, name: str, expected: str) -> None:
            if not ok:
                raise CompensatorError(f"{path}: {name}={_short(data.get(name))}: expected "
                                       f"{expected}")

        def is_int(v: Any) -> bool:
            return isinstance(v, int) and not isinstance(v, bool)

        def is_real(v: Any) -> bool:  # finite; a huge JSON integer is no float
            return (isinstance(v, (int, float)) and not isinstance(v, bool)
                    and abs(v) <= 1e300 and bool(np.isfinite(float(v))))

        def one_of(v: Any, choices: Collection[str]) -> bool:  # a list is no dict key
            return isinstance(v, str) and v in choices

        need(one_of(data["algo"], ("sac", "ppo")), "algo", "'sac' or 'ppo'")
        need(is_int(data["obs_dim"]) and data["obs_dim"] > 0, "obs_dim", "a positive integer")
        need(is_int(data["act_dim"]) and data["act_dim"] > 0, "act_dim", "a positive integer")
        arch = data["net_arch"]
        need(isinstance(arch, list) and len(arch) > 0 and all(is_int(w) and w > 0 for w in arch),
             "net_arch", "a non-empty list of positive integers")
        n_params = _n_params(data["obs_dim"], data["act_dim"], arch)
        if n_params * 4 > MAX_MODEL_BYTES:
            raise CompensatorError(
                f"{path}: obs_dim={data['obs_dim']}, act_dim={data['act_dim']}, "
                f"net_arch={_short(arch)} declare {n_params} parameters; expected at most "
                f"{MAX_MODEL_BYTES // 4} (float32 weights of at most {MAX_MODEL_BYTES} bytes)")
        need(one_of(data["activation"], _ACTIVATIONS), "activation",
             f"one of {sorted(_ACTIVATIONS)}")
        need(one_of(data["squash"], _SQUASH), "squash", f"one of {_SQUASH}")
        need(one_of(data["action_mode"], ("force", "offset")), "action_mode",
             "'force' or 'offset'")
        scale = data["action_scale"]
        need(is_real(scale) and scale > 0, "action_scale", "a positive number")
        need(isinstance(data["env_id"], str), "env_id", "a string")
        wname = data["weights"]
        need(isinstance(wname, str) and wname not in ("", ".", "..") and "/" not in wname
             and "\\" not in wname and "\0" not in wname, "weights",
             "a file name next to the JSON")
        norm = []
        for name in ("obs_mean", "obs_std"):
            val = data.get(name)
            if val is not None:
                need(isinstance(val, list) and len(val) == data["obs_dim"]
                     and all(is_real(v) for v in val),
                     name, f"null or a list of {data['obs_dim']} finite numbers")
                val = tuple(float(v) for v in val)
            norm.append(val)
        if (norm[0] is None) != (norm[1] is None):
            raise CompensatorError(f"{path}: obs_mean and obs_std must both be given or both null")
        if norm[1] is not None and min(norm[1]) <= 0.0:
            raise CompensatorError(f"{path}: obs_std must be positive")
        training = data.get("training", {})
        need(isinstance(training, dict), "training", "an object")
        return cls(algo=data["algo"], obs_dim=data["obs_dim"], act_dim=data["act_dim"],
                   net_arch=tuple(arch), activation=data["activation"], squash=data["squash"],
                   action_mode=data["action_mode"], action_scale=float(scale),
                   env_id=data["env_id"], weights=wname, obs_mean=norm[0], obs_std=norm[1],
                   training=training)


def _short(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters (values read from a file can be huge)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _n_params(obs_dim: int, act_dim: int, net_arch: Sequence[int]) -> int:
    """Weights and biases of :class:`PolicyMLP` (exact integers: nothing is allocated)."""
    widths = [obs_dim, *net_arch, act_dim]
    return sum(w_in * w_out + w_out for w_in, w_out in zip(widths[:-1], widths[1:], strict=True))


class PolicyMLP(nn.Module):
    """The deterministic actor as a plain torch MLP.

    Parameters
    ----------
    obs_dim, act_dim : int
    net_arch : sequence of int
    activation : {"relu", "tanh"}
    """

    def __init__(self, obs_dim: int, act_dim: int, net_arch: Sequence[int],
                 activation: str) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        width = obs_dim
        for w in net_arch:
            layers += [nn.Linear(width, w), _ACTIVATIONS[activation]()]
            width = w
        self.hidden = nn.Sequential(*layers)
        self.out = nn.Linear(width, act_dim)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """Pre-squash output."""
        return self.out(self.hidden(obs))


class NumpyPolicy:
    """Fast inference of a loaded policy (numpy, float64; each row as if it were alone).

    Parameters
    ----------
    spec : PolicySpec
    state_dict : mapping of str to Tensor
        Weights of :class:`PolicyMLP` for ``spec``.
    """

    def __init__(self, spec: PolicySpec, state_dict: Mapping[str, torch.Tensor]) -> None:
        self.spec = spec
        linears = [k[: -len(".weight")] for k in state_dict if k.endswith(".weight")]
        self._w = [state_dict[k + ".weight"].detach().double().numpy().T.copy() for k in linears]
        self._b = [state_dict[k + ".bias"].detach().double().numpy().copy() for k in linears]
        self._act = np.tanh if spec.activation == "tanh" else (lambda z: np.maximum(z, 0.0))
        self._mean = None if spec.obs_mean is None else np.asarray(spec.obs_mean)
        self._std = None if spec.obs_std is None else np.asarray(spec.obs_std)

    def same_as(self, other: NumpyPolicy) -> bool:
        """Whether ``other`` is the same policy (spec and weights equal), so that one call
        may act for both."""
        return (isinstance(other, NumpyPolicy) and self.spec == other.spec
                and all(np.array_equal(a, b) for a, b in zip(self._w, other._w, strict=True))
                and all(np.array_equal(a, b) for a, b in zip(self._b, other._b, strict=True)))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Actions in [-1, 1], shape (N, act_dim), for observations of shape (N, obs_dim).

        Row ``i`` of the result is a function of row ``i`` of ``obs`` alone, bit for bit,
        whatever ``N`` and the other rows.
        """
        h = np.asarray(obs, dtype=np.float64)
        if self._mean is not None and self._std is not None:
            h = (h - self._mean) / self._std
        for w, b in zip(self._w[:-1], self._b[:-1], strict=True):
            h = self._act(_rows_times(h, w) + b)
        z = _rows_times(h, self._w[-1]) + self._b[-1]
        return np.tanh(z) if self.spec.squash == "tanh" else np.clip(z, -1.0, 1.0)


def _rows_times(h: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``h @ w`` with each row's result independent of the other rows.

    BLAS ``h @ w`` blocks its sums by the number of rows (gemv for one, gemm for more), so one
    observation's action would change with the batch it is stepped in; numpy's own einsum
    loop (``optimize=False``: no BLAS) sums each row the same way whatever the rows.
    """
    return np.einsum("nk,ko->no", h, w, optimize=False)


def save_policy(json_path: str | Path, spec: PolicySpec, module: PolicyMLP) -> None:
    """Write ``spec`` as JSON and ``module``'s weights next to it (``spec.weights``)."""
    json_path = Path(json_path)
    json_path.parent.mkdir(parents=True, exist_ok=True)
    weights = json_path.parent / spec.weights
    state = {k: v.detach().cpu().clone() for k, v in module.state_dict().items()}
    tmp_w = weights.with_name(weights.name + ".tmp")
    torch.save(state, tmp_w)
    tmp_w.replace(weights)
    tmp_j = json_path.with_name(json_path.name + ".tmp")
    tmp_j.write_text(spec.to_json(), encoding="utf-8")
    tmp_j.replace(json_path)


def load_policy(json_path: str | Path) -> NumpyPolicy:
    """Load a policy written by :func:`save_policy`.

    Raises
    ------
    CompensatorError
        Naming the file, when either file is missing, unreadable, or does not match.
    """
    json_path = Path(json_path)
    try:
        data = parse_json(read_file(json_path, MAX_JSON_BYTES), str(json_path))
    except FileNotFoundError as exc:
        raise CompensatorError(f"{json_path}: cannot read policy JSON: no such file") from exc
    except UnsafeFileError as exc:
        raise CompensatorError(f"{exc} (policy JSON)") from None
    spec = PolicySpec.from_dict(data, str(json_path))
    wpath = json_path.parent / spec.weights
    try:
        state = load_tensors(read_file(wpath, MAX_MODEL_BYTES), str(wpath))
    except FileNotFoundError as exc:
        raise CompensatorError(f"{wpath}: policy weights not found (named by {json_path})") \
            from exc
    except UnsafeFileError as exc:
        raise CompensatorError(f"{exc} (policy weights named by {json_path})") from None
    module = PolicyMLP(spec.obs_dim, spec.act_dim, spec.net_arch, spec.activation)
    try:
        module.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        raise CompensatorError(f"{wpath}: weights do not match the network in {json_path} "
                               f"(obs_dim={spec.obs_dim}, net_arch={list(spec.net_arch)}): "
                               f"{exc}") from exc
    if not all(bool(torch.isfinite(v).all()) for v in state.values()):
        raise CompensatorError(f"{wpath}: weights contain NaN or inf")
    return NumpyPolicy(spec, module.state_dict())
