"""One small generic registry for friction models, trajectories, predictors, compensators,
diagnosis effects and env specs.

Modelled on Gymnasium's env registry: ids are versioned strings (``name-v0`` or plain names),
entry points are ``"package.module:Attribute"`` strings imported lazily, re-registering an id is
an error, and an unknown id raises with "did you mean" suggestions. Third-party packages add
entries through the Python entry-point group ``fricbench.<kind>`` (for example
``fricbench.predictors``); each entry point names a callable to register, or an object exposing
``register(registry)``.
"""

from __future__ import annotations

import difflib
import importlib
import importlib.metadata
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

__all__ = [
    "DuplicateIdError",
    "Registry",
    "RegistryEntry",
    "UnknownIdError",
    "did_you_mean",
    "load_entry_point",
]

T = TypeVar("T")


class UnknownIdError(KeyError):
    """An id that is not registered; the message lists the closest registered ids."""

    def __str__(self) -> str:  # KeyError quotes its argument; we want the plain sentence
        return str(self.args[0]) if self.args else ""


class DuplicateIdError(ValueError):
    """Registering an id that already exists."""


def did_you_mean(name: object, choices: Iterable[str], cutoff: float = 0.5) -> str:
    """The hint appended to an "unknown name" message: ``"; did you mean 'a', 'b'?"`` or ``""``.

    Parameters
    ----------
    name : object
        The unknown name (non-strings are compared by their ``str``).
    choices : iterable of str
        The valid names.
    cutoff : float
        Similarity threshold of :func:`difflib.get_close_matches` (0..1).
    """
    close = difflib.get_close_matches(str(name), list(choices), n=3, cutoff=cutoff)
    return f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""


def load_entry_point(entry_point: str) -> Any:
    """Import ``"package.module:Attribute"`` and return the attribute.

    Raises
    ------
    ValueError
        If the string is not of the form ``module:attribute``.
    ImportError
        If the module or attribute cannot be found.
    """
    if not isinstance(entry_point, str) or entry_point.count(":") != 1:
        raise ValueError(
            f"entry_point={entry_point!r}: expected a string 'package.module:Attribute'"
        )
    module_name, attr = entry_point.split(":")
    module = importlib.import_module(module_name)
    try:
        return getattr(module, attr)
    except AttributeError as exc:
        raise ImportError(f"module {module_name!r} has no attribute {attr!r}") from exc


@dataclass(frozen=True)
class RegistryEntry:
    """One registered id: where its factory lives and the keyword defaults it is made with."""

    id: str
    entry_point: str | Callable[..., Any]
    kwargs: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    data: Any = None
    """What the id stands for beyond its factory, if a registry keeps it (an env's parsed
    spec); ``None`` otherwise."""

    def load(self) -> Callable[..., Any]:
        """Return the factory (class or function), importing it if needed."""
        if callable(self.entry_point):
            return self.entry_point
        return load_entry_point(self.entry_point)


class Registry(Generic[T]):
    """A mapping from ids to factories, with lazy loading and plug-ins.

    Parameters
    ----------
    kind : str
        Human name of what is registered ("friction model", "trajectory", ...), used in messages.
    group : str
        Python entry-point group scanned once for third-party plug-ins, e.g.
        ``"fricbench.friction"``.
    """

    def __init__(self, kind: str, group: str) -> None:
        self.kind = kind
        self.group = group
        self._entries: dict[str, RegistryEntry] = {}
        self._plugins_loaded = False
        self._builtins: list[Callable[[], None]] = []

    # -- registration -----------------------------------------------------------------------
    def register(
        self,
        id: str,
        entry_point: str | Callable[..., Any],
        *,
        kwargs: dict[str, Any] | None = None,
        description: str = "",
        data: Any = None,
    ) -> None:
        """Register ``id``; raises :class:`DuplicateIdError` if it exists already.

        ``data`` is kept on the entry (:attr:`RegistryEntry.data`) for registries whose ids
        stand for more than a factory (an env id for its parsed spec).
        """
        if not isinstance(id, str) or not id or id != id.strip():
            raise ValueError(f"id={id!r}: expected a non-empty string without surrounding spaces")
        if id in self._entries:
            raise DuplicateIdError(f"{self.kind} id {id!r} is already registered")
        self._entries[id] = RegistryEntry(id, entry_point, dict(kwargs or {}), description,
                                          data)

    def unregister(self, id: str) -> None:
        """Remove ``id`` (used by tests and by plug-ins that replace their own entries)."""
        self._ensure_plugins()
        if id not in self._entries:
            raise self._unknown(id)
        del self._entries[id]

    # -- look-up ----------------------------------------------------------------------------
    def spec(self, id: str) -> RegistryEntry:
        """Return the entry of ``id`` or raise :class:`UnknownIdError` with near matches."""
        self._ensure_plugins()
        if not isinstance(id, str) or id not in self._entries:
            raise self._unknown(id)
        return self._entries[id]

    def make(self, id: str, **kwargs: Any) -> T:
        """Build a new instance of ``id``; ``kwargs`` override the registered defaults."""
        entry = self.spec(id)
        factory = entry.load()
        return factory(**{**entry.kwargs, **kwargs})  # type: ignore[no-any-return]

    def ids(self, sort: bool = True) -> list[str]:
        """All registered ids, sorted (or in registration order with ``sort=False``)."""
        self._ensure_plugins()
        return sorted(self._entries) if sort else list(self._entries)

    def __contains__(self, id: object) -> bool:
        self._ensure_plugins()
        return id in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self.ids())

    def __len__(self) -> int:
        return len(self.ids())

    # -- internals --------------------------------------------------------------------------
    def _unknown(self, id: object) -> UnknownIdError:
        names = list(self._entries)
        return UnknownIdError(
            f"unknown {self.kind} id {id!r}{did_you_mean(id, names)} "
            f"(registered: {', '.join(sorted(names))})"
        )

    def _ensure_plugins(self) -> None:
        if self._plugins_loaded:
            return
        self._plugins_loaded = True
        for ep in importlib.metadata.entry_points(group=self.group):
            self._load_plugin(ep)

    def _load_plugin(self, ep: importlib.metadata.EntryPoint) -> None:
        """Let the plug-in ``ep`` register its ids: it names a callable taking the registry,
        or an object with ``register(registry)``."""
        obj = ep.load()
        if hasattr(obj, "register") and not isinstance(obj, type):
            obj.register(self)
        elif callable(obj):
            obj(self)
        else:
            raise TypeError(
                f"entry point {ep.name!r} in group {self.group!r} must be callable "
                f"(got {type(obj).__name__})"
            )
