"""The generic registry: ids, near matches, duplicates and real entry-point plug-ins."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from fricbench.registry import DuplicateIdError, Registry, UnknownIdError, load_entry_point


def _make(**kw: object) -> dict[str, object]:
    return kw


def test_register_make_and_list() -> None:
    reg: Registry[dict[str, object]] = Registry("thing", "fricbench.tests.none")
    reg.register("alpha-v0", _make, kwargs={"a": 1})
    assert reg.make("alpha-v0") == {"a": 1}
    assert reg.make("alpha-v0", a=2) == {"a": 2}
    assert reg.ids() == ["alpha-v0"] and "alpha-v0" in reg and len(reg) == 1


def test_unknown_id_suggests_near_matches() -> None:
    reg: Registry[object] = Registry("thing", "fricbench.tests.none")
    reg.register("stribeck", _make)
    with pytest.raises(UnknownIdError, match="did you mean 'stribeck'"):
        reg.make("stribek")


def test_duplicate_is_an_error() -> None:
    reg: Registry[object] = Registry("thing", "fricbench.tests.none")
    reg.register("a", _make)
    with pytest.raises(DuplicateIdError, match="already registered"):
        reg.register("a", _make)


@pytest.mark.parametrize("bad", ["", " a", "a "])
def test_bad_ids_rejected(bad: str) -> None:
    with pytest.raises(ValueError, match="id="):
        Registry("thing", "g").register(bad, _make)


def test_load_entry_point_errors() -> None:
    with pytest.raises(ValueError, match="package.module:Attribute"):
        load_entry_point("no_colon")
    with pytest.raises(ImportError, match="no attribute"):
        load_entry_point("fricbench.registry:Nope")


def test_plugin_through_entry_point_group(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A third-party distribution on sys.path registers through ``fricbench.friction``."""
    pkg = tmp_path / "fb_plugin_demo.py"
    pkg.write_text(
        "from dataclasses import dataclass\n"
        "from fricbench.friction import Coulomb\n"
        "@dataclass(frozen=True)\n"
        "class Sticky(Coulomb):\n"
        "    id = 'sticky-demo'\n"
        "def register(registry):\n"
        "    registry.register('sticky-demo', 'fb_plugin_demo:Sticky')\n"
    )
    dist = tmp_path / "fb_plugin_demo-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: fb-plugin-demo\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "[fricbench.friction]\nsticky = fb_plugin_demo:register\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    reg: Registry[object] = Registry("friction model", "fricbench.friction")
    reg.register("coulomb", "fricbench.friction.models:Coulomb")
    assert "sticky-demo" in reg.ids()
    model = reg.make("sticky-demo", fc=10.0)
    assert type(model).__name__ == "Sticky" and model.fc == 10.0
    sys.modules.pop("fb_plugin_demo", None)
