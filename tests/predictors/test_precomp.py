"""Pre-compensation: x_r' = x_r + e_pred, one-shot and iterated, measured on the simulator."""

from __future__ import annotations

import numpy as np
import pytest

from fricbench.axis import Axis, simulate
from fricbench.predictors import make_predictor
from fricbench.predictors.precomp import precompensated_reference, precompensation_offset
from fricbench.trajectories import make_trajectory


@pytest.fixture(scope="module")
def linear_setup():
    """A friction-free axis and a TF predictor fitted on it: only the linear error remains."""
    axis = Axis().without_friction().with_effects(quantization=0.25e-6)
    train = simulate(axis, make_trajectory("m_serial", stroke=0.015, feed=0.03, accel=0.8,
                                           stroke_scales=(1.0, 0.5), feed_scales=(1.0, 0.4)))
    pred = make_predictor("tf").fit([train])
    return axis, pred, make_trajectory("m_serial")


def test_one_shot_offset_is_the_predicted_error(linear_setup) -> None:
    _, pred, ref = linear_setup
    np.testing.assert_allclose(precompensation_offset(pred, ref), pred.predict_error(ref))


def test_tf_precompensation_removes_the_linear_error(linear_setup) -> None:
    axis, pred, ref = linear_setup
    none = simulate(axis, ref).max_error
    one = simulate(axis, ref, u_offset=precompensation_offset(pred, ref)).max_error
    it3 = simulate(axis, ref, u_offset=precompensation_offset(pred, ref, iterations=3)).max_error
    # one shot removes the first-order part ((1 - G) x_r); iterating removes (1 - G)^n x_r too
    assert one < 0.3 * none
    assert it3 < 0.5 * one


def test_iterations_converge_to_the_predicted_inverse(linear_setup) -> None:
    _, pred, ref = linear_setup

    def mismatch(iterations: int) -> float:
        off = precompensation_offset(pred, ref, iterations=iterations, gain=0.5)
        # how far the predicted response to the commanded reference is from the nominal one
        return float(np.max(np.abs(pred.predict(precompensated_reference(ref, off)) - ref.x)))

    m1, m4, m12 = mismatch(1), mismatch(4), mismatch(12)
    assert m12 < m4 < m1
    assert m12 < 0.05 * m1


def test_bad_arguments(linear_setup) -> None:
    _, pred, ref = linear_setup
    with pytest.raises(ValueError, match="iterations"):
        precompensation_offset(pred, ref, iterations=0)
    with pytest.raises(ValueError, match="gain"):
        precompensation_offset(pred, ref, gain=1.5)
    with pytest.raises(TypeError, match="Predictor"):
        precompensation_offset(object(), ref)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="offset has shape"):
        precompensated_reference(ref, np.zeros(3))


def test_model_inverse_one_shot_beats_the_plain_shift_on_the_linear_error(linear_setup) -> None:
    axis, pred, ref = linear_setup
    one = simulate(axis, ref, u_offset=precompensation_offset(pred, ref)).max_error
    inv = simulate(axis, ref, u_offset=precompensation_offset(pred, ref, inverse=True)).max_error
    # the shift x_r + e_pred reaches the position through G (late, smaller); G^-1 does not
    assert inv < 0.5 * one


def test_model_inverse_needs_a_transfer_function(linear_setup) -> None:
    _, pred, ref = linear_setup

    class NoTF(type(pred)):  # type: ignore[misc]
        pass

    bare = NoTF.__new__(NoTF)
    bare.ts_ = pred.ts_
    bare._predict_position = lambda x: x  # type: ignore[method-assign]
    with pytest.raises(ValueError, match="tf_"):
        precompensation_offset(bare, ref, inverse=True)
    with pytest.raises(ValueError, match="beta"):
        precompensation_offset(pred, ref, inverse=True, beta=0.0)
    with pytest.raises(ValueError, match="cutoff"):
        precompensation_offset(pred, ref, inverse=True, q_cutoff=600.0)
