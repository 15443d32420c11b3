"""Pre-compensation compensators: settings and what ``greybox-precomp`` achieves."""

from __future__ import annotations

import pytest

from fricbench.bench.runner import run_benchmark
from fricbench.compensators import make_compensator


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"gain": 0.0}, "gain"),
    ({"gain": 1.5}, "gain"),
    ({"advance": -1}, "advance"),
    ({"iterations": 0}, "iterations"),
])
@pytest.mark.parametrize("cid", ["tf-precomp", "greybox-precomp"])
def test_bad_settings_are_named(cid: str, kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make_compensator(cid, **kwargs)


def test_greybox_precomp_cuts_the_m_serial_error() -> None:
    """Fitted on the env's random training references, scored on M-serial (not among them)."""
    recs = {r.compensator: r for r in run_benchmark(
        ["fricbench/PaperAxis-v0"], ["none", "greybox-precomp"], [0], ["m_serial"], n_jobs=1,
        progress=False)}
    assert all(r.status == "ok" for r in recs.values())
    assert recs["greybox-precomp"].max_error < 0.4 * recs["none"].max_error
