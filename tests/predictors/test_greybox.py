"""``greybox``: the identified closed loop as a predictor."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest
import torch

from fricbench.axis import Axis, simulate
from fricbench.predictors import Predictor, PredictorFileError, make_predictor
from fricbench.predictors.greybox import GreyBoxPredictor, loop_inputs
from fricbench.trajectories import make_trajectory

from .test_persistence import _rewrite


@pytest.fixture(scope="module")
def fitted(small_runs) -> dict[str, Predictor]:
    return {law: make_predictor("greybox", friction=law).fit(small_runs)
            for law in ("stribeck", "coulomb")}


def _max_um(pred: Predictor, ref, run) -> float:
    return float(np.max(np.abs(run.x_true - pred.predict(ref))) * 1e6)


def test_predicts_stick_slip_on_held_out_runs(fitted, small_runs, small_reference) -> None:
    """Trained on two noisy runs of the small curve, tested on a third seed and on M-serial
    (never seen): far below the TF-only error, and the Stribeck term matters."""
    axis = Axis().with_effects(noise_std=0.1e-6, quantization=0.25e-6)
    held_out = simulate(axis, small_reference, seed=3)
    tf = make_predictor("tf").fit(small_runs)
    e_tf = _max_um(tf, small_reference, held_out)
    e_gb = _max_um(fitted["stribeck"], small_reference, held_out)
    assert e_gb < e_tf / 10.0
    assert e_gb < _max_um(fitted["coulomb"], small_reference, held_out) / 2.0
    ms = make_trajectory("m_serial")
    other = simulate(axis, ms, seed=4)
    assert _max_um(fitted["stribeck"], ms, other) < _max_um(tf, ms, other) / 4.0


def test_fitted_loop_is_a_stable_servo(fitted) -> None:
    m = fitted["stribeck"].model_
    assert m.effects == ("coulomb_friction", "stribeck_friction")
    c = m.controller
    assert c.wv > 0 and c.kp > 0 and c.ki > 0
    assert 0.9 < c.kvff < 1.1  # the default axis has full velocity feedforward
    assert np.isfinite(fitted["stribeck"].cost_)


def test_loop_inputs_start_at_rest_on_the_reference() -> None:
    x = np.linspace(0.0, 1e-3, 50) ** 2 + 0.01
    inp = loop_inputs(x, 1e-3)
    assert inp.x0 == x[0] and inp.v0 == 0.0
    np.testing.assert_allclose(inp.vr, np.gradient(x, 1e-3))
    assert inp.t[1] == pytest.approx(1e-3)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"friction": "lugre"}, "friction='lugre'"),
    ({"vs_starts": ()}, "vs_starts"),
    ({"vs_starts": (0.1, 1.5)}, "vs_starts"),
    ({"vs_starts": "0.1"}, "vs_starts"),
    ({"max_iter": 0}, "max_iter"),
    ({"n_poles": 2, "n_zeros": 2}, "n_zeros"),
])
def test_constructor_rejects_bad_settings(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        GreyBoxPredictor(**kwargs)


def test_non_finite_stored_loop_is_refused(fitted, tmp_path) -> None:
    path = tmp_path / "gb.fbp"
    fitted["stribeck"].save(path)
    with zipfile.ZipFile(path) as zf:
        state = torch.load(io.BytesIO(zf.read("weights.pt")), weights_only=True)
    state["plant_"][2] = float("nan")
    bad = _rewrite(path, tmp_path / "bad.fbp", state=state)
    with pytest.raises(PredictorFileError, match="non-finite"):
        Predictor.load(bad)


def test_greybox_lstm_adds_the_network_to_the_grey_box(small_runs, small_reference,
                                                      make_fast, tmp_path) -> None:
    pred = make_fast("greybox+lstm").fit(small_runs)
    assert isinstance(pred.base_, GreyBoxPredictor)
    np.testing.assert_allclose(pred.predict(small_reference),
                               pred.base_.predict(small_reference)
                               + pred.predict_friction_error(small_reference.x))
    # the saved file carries the grey box; without it the file is refused
    path = tmp_path / "gbl.fbp"
    pred.save(path)
    with zipfile.ZipFile(path) as zf:
        state = torch.load(io.BytesIO(zf.read("weights.pt")), weights_only=True)
    assert "base.plant_" in state and "base.ts_" in state
    del state["base.plant_"]
    bad = _rewrite(path, tmp_path / "bad.fbp", state=state)
    with pytest.raises(PredictorFileError, match="base.plant_"):
        Predictor.load(bad)


def test_unknown_base_is_named() -> None:
    with pytest.raises(ValueError, match="base='arx'"):
        make_predictor("tf+lstm", base="arx")
