"""Execute every teaching notebook in docs/tutorials/ end to end; any cell error fails.

The notebooks are committed with their outputs cleared; running them here (``make test``) draws
every picture and recomputes every number, so a change that breaks a tutorial fails CI.
"""

from __future__ import annotations

import time
from pathlib import Path

import nbclient
import nbformat
import pytest

TUTORIALS = Path(__file__).resolve().parents[1] / "docs" / "tutorials"
NOTEBOOKS = sorted(TUTORIALS.glob("*.ipynb"))
CELL_TIMEOUT = 120  # s, per cell
NOTEBOOK_BUDGET = 90  # s, per notebook (each is written to run in well under 40 s)


def test_tutorials_exist() -> None:
    assert NOTEBOOKS, f"no notebooks in {TUTORIALS}"


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_tutorial_runs(path: Path, tmp_path: Path) -> None:
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(
        nb, timeout=CELL_TIMEOUT, kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},  # anything a notebook writes goes here
    )
    t0 = time.perf_counter()
    client.execute()  # raises CellExecutionError on the first failing cell
    elapsed = time.perf_counter() - t0
    images = sum("image/png" in out.get("data", {})
                 for cell in nb.cells if cell.cell_type == "code" for out in cell.outputs)
    assert images >= 1, f"{path.name} drew no picture"
    assert elapsed < NOTEBOOK_BUDGET, f"{path.name} took {elapsed:.0f} s"
