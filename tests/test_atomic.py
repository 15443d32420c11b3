"""Atomic writes: whole files or nothing, with the permissions the user's umask gives."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from fricbench._atomic import atomic_write, atomic_write_via


@pytest.fixture
def umask() -> Iterator[None]:
    """Restore the process umask after the test."""
    old = os.umask(0o022)
    yield
    os.umask(old)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o077, 0o027])
def test_written_file_gets_the_umask_mode(tmp_path: Path, umask: None, mask: int) -> None:
    os.umask(mask)
    target = tmp_path / "sub" / "table.csv"
    atomic_write(target, "a,b\n")
    assert _mode(target) == 0o666 & ~mask
    # replacing keeps it atomic and gives the same mode
    os.chmod(target, 0o600)
    atomic_write(target, b"c,d\n")
    assert target.read_bytes() == b"c,d\n"
    assert _mode(target) == 0o666 & ~mask
    assert sorted(p.name for p in target.parent.iterdir()) == ["table.csv"]


def test_write_via_callback_gets_the_umask_mode(tmp_path: Path, umask: None) -> None:
    os.umask(0o022)
    target = tmp_path / "figure.png"
    atomic_write_via(target, lambda tmp: Path(tmp).write_bytes(b"png"))
    assert _mode(target) == 0o644 and target.read_bytes() == b"png"


def test_failed_write_leaves_the_old_file_and_no_temp(tmp_path: Path) -> None:
    target = tmp_path / "model.fbp"
    atomic_write(target, b"old")

    def fail(tmp: str) -> None:
        Path(tmp).write_bytes(b"half")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        atomic_write_via(target, fail)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["model.fbp"]
