"""Atomic file writes: a temp file in the target's folder, then ``os.replace``.

A reader never sees a half-written leaderboard, model or report, and a failed write leaves the
previous file untouched. The written file gets the permissions any newly created file gets
(``0o666`` less the user's umask, e.g. ``0o644``), not :func:`tempfile.mkstemp`'s ``0o600``:
the temp file is created with mode ``0o666`` and the kernel applies the umask.
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Callable
from pathlib import Path

__all__ = ["atomic_write", "atomic_write_via"]


def _create_temp(target: Path) -> str:
    """Create a new, empty temp file next to ``target`` with mode ``0o666 & ~umask``."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(100):
        tmp = str(target.parent / f".{target.name}.{secrets.token_hex(6)}.tmp")
        try:
            fd = os.open(tmp, flags, 0o666)  # the umask applies, as for any new file
        except FileExistsError:
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(f"no unused temp file name next to {target}")


def atomic_write_via(path: str | os.PathLike[str], write: Callable[[str], None]) -> None:
    """Call ``write(tmp_path)`` (e.g. ``fig.savefig``), then move the temp file onto ``path``.

    The result has mode ``0o666 & ~umask`` (see the module docstring), whether ``path``
    existed or not.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = _create_temp(target)
    try:
        write(tmp)
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write(path: str | os.PathLike[str], data: str | bytes) -> None:
    """Write text (UTF-8) or bytes to ``path`` atomically, flushed to disk before the rename."""
    payload = data.encode("utf-8") if isinstance(data, str) else data

    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(payload)
            fh.flush()
            os.fsync(fh.fileno())

    atomic_write_via(path, write)
