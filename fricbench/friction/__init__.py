"""Friction models: one pure vectorised force law each, registered by id.

``make_friction("stribeck", fc=120.0)`` builds one; ``friction_registry.ids()`` lists them;
third parties add models through the entry-point group ``fricbench.friction``.
"""

from __future__ import annotations

from typing import Any

from fricbench.friction.base import FrictionModel
from fricbench.friction.models import Coulomb, Dahl, LuGre, Stribeck, Viscous
from fricbench.registry import Registry

__all__ = [
    "Coulomb",
    "Dahl",
    "FrictionModel",
    "LuGre",
    "Stribeck",
    "Viscous",
    "friction_registry",
    "make_friction",
]

friction_registry: Registry[FrictionModel] = Registry("friction model", "fricbench.friction")
for _cls in (Coulomb, Viscous, Stribeck, LuGre, Dahl):
    friction_registry.register(_cls.id, f"fricbench.friction.models:{_cls.__name__}",
                               description=(_cls.__doc__ or "").strip().splitlines()[0])


def make_friction(id: str, **params: Any) -> FrictionModel:
    """Build the friction model registered as ``id`` with the given SI parameters."""
    return friction_registry.make(id, **params)
