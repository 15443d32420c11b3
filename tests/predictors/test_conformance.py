"""Every registered predictor through the same checks (the shared conformance test)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fricbench.predictors import (
    NotFittedError,
    Predictor,
    Run,
    make_predictor,
    predictor_registry,
)
from fricbench.registry import UnknownIdError
from fricbench.trajectories import Reference

IDS = predictor_registry.ids()


def test_the_paper_ids_are_registered() -> None:
    assert {"tf", "tf+lstm", "tf+stribeck"} <= set(IDS)
    with pytest.raises(UnknownIdError, match="did you mean"):
        make_predictor("tf+lstn")


@pytest.mark.parametrize("pid", IDS)
def test_conformance(pid: str, small_runs, small_reference, tmp_path, make_fast) -> None:
    pred = make_fast(pid)
    assert isinstance(pred, Predictor)
    assert not pred.is_fitted
    with pytest.raises(NotFittedError):
        pred.predict(small_reference)
    with pytest.raises(NotFittedError):
        pred.save(tmp_path / "unfitted.fbp")

    # fit returns self; accepts SimulationResult and Run alike
    runs = [small_runs[0], Run(small_runs[1].t, small_runs[1].x_ref, small_runs[1].x)]
    assert pred.fit(runs) is pred
    assert pred.is_fitted and pred.ts_ == pytest.approx(1e-3)
    assert all(not k.startswith("_") for k in vars(pred) if k.endswith("_"))

    x_pred = pred.predict(small_reference)
    assert x_pred.shape == small_reference.x.shape
    assert np.all(np.isfinite(x_pred))
    np.testing.assert_allclose(pred.predict_error(small_reference), small_reference.x - x_pred)
    # a sensible prediction: within 50 um of the true position of a run of this reference
    assert np.max(np.abs(x_pred - small_runs[0].x_true)) < 50e-6

    # save / load round trip, through the base class and the concrete class
    path = tmp_path / f"{pid}.fbp"
    pred.save(path)
    for loader in (Predictor, type(pred)):
        again = loader.load(path)
        assert type(again) is type(pred)
        assert again.get_params() == pred.get_params()
        np.testing.assert_array_equal(again.predict(small_reference), x_pred)

    # deterministic for the same settings
    twin = make_fast(pid).fit(runs)
    np.testing.assert_array_equal(twin.predict(small_reference), x_pred)

    # a reference at another sample rate is refused
    slow = Reference.from_positions(small_reference.t[::2], small_reference.x[::2])
    with pytest.raises(ValueError, match="resample"):
        pred.predict(slow)


@pytest.mark.parametrize("pid", IDS)
def test_bad_training_data(pid: str, small_runs, make_fast) -> None:
    run = small_runs[0]
    pred = make_fast(pid)
    with pytest.raises(TypeError, match="list of runs"):
        pred.fit(run)
    with pytest.raises(ValueError, match="empty"):
        pred.fit([])
    x_nan = run.x.copy()
    x_nan[100] = np.nan
    with pytest.raises(ValueError, match=r"runs\[0\]\.x contains NaN"):
        pred.fit([Run(run.t, run.x_ref, x_nan)])
    with pytest.raises(ValueError, match="same length"):
        pred.fit([Run(run.t, run.x_ref, run.x[:-5])])
    flat = np.full_like(run.x_ref, 0.01)
    with pytest.raises(ValueError, match="no motion"):
        pred.fit([Run(run.t, flat, flat)])
    with pytest.raises(ValueError, match="sample time"):
        pred.fit([run, replace(run, t=run.t * 2)])


@pytest.mark.parametrize("pid", [p for p in IDS if p != "tf"])
def test_friction_predictors_need_a_reversal(pid: str, make_fast) -> None:
    from fricbench.axis import Axis, simulate
    from fricbench.trajectories import make_trajectory

    one_way = make_trajectory("s_curve", back=False)
    res = simulate(Axis(), one_way)
    with pytest.raises(ValueError, match="no reversal"):
        make_fast(pid).fit([res])
