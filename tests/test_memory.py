"""The memory figure: the machine's available memory, lowered by ``ulimit -v``."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from fricbench._memory import available_memory, check_memory, format_bytes

resource = pytest.importorskip("resource")


def test_the_machine_figure_is_positive() -> None:
    avail = available_memory()
    assert avail is not None and avail[0] > 0


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc")
def test_address_space_limit_lowers_the_figure() -> None:
    used = int(Path("/proc/self/statm").read_text().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (used + 2**30, hard))
    try:
        room, what = available_memory()  # type: ignore[misc]
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    assert "ulimit -v" in what and room <= 2**30


def test_check_memory_names_argument_and_figures(monkeypatch: pytest.MonkeyPatch) -> None:
    import fricbench._memory as memory

    monkeypatch.setattr(memory, "available_memory", lambda: (1_500_000, "test limit"))
    check_memory("n=1", 1_000_000, "1 MB", lambda room: "")
    with pytest.raises(ValueError, match=r"^n=2: needs about 2 MB of memory \(1 MB each\) but "
                                         r"1\.5 MB is available \(test limit\); expected n <= 1$"):
        check_memory("n=2", 2_000_000, "1 MB each", lambda room: f"n <= {room // 1_000_000}")
    assert format_bytes(512) == "512 B" and format_bytes(2.5e12) == "2.5 TB"
