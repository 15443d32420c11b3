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


def test_any_registered_predictor_is_a_precompensation_by_id() -> None:
    from fricbench.compensators import make_compensator
    from fricbench.compensators.precomp import Precompensation

    comp = make_compensator("precomp:tf+lstm-phys", n_runs=1)
    assert isinstance(comp, Precompensation)
    assert comp.id == "precomp:tf+lstm-phys" and comp.predictor == "tf+lstm-phys"
    # the registered variants are the same class with other keywords, named by their id
    grey = make_compensator("greybox-precomp")
    assert type(grey) is Precompensation and grey.id == "greybox-precomp"
    assert (grey.predictor, grey.iterations, grey.gain, grey.advance) == ("greybox", 10, 0.5, 3)
    with pytest.raises(ValueError, match=r"predictor='tf\+lstmm'.*did you mean 'tf\+lstm"):
        make_compensator("precomp:tf+lstmm")


def test_one_not_fitted_error() -> None:
    from fricbench.compensators import NotFittedError as CompNotFitted
    from fricbench.exceptions import NotFittedError
    from fricbench.predictors import NotFittedError as PredNotFitted

    assert CompNotFitted is NotFittedError is PredNotFitted
