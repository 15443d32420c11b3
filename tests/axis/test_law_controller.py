"""The identified linear law as the axis's controller (``ControllerParams.law = "linear"``)."""

from __future__ import annotations

import control
import numpy as np
import pytest

from fricbench.axis import Axis, closed_loop, linear_law, simulate
from fricbench.axis.params import ControllerParams
from fricbench.axis.plant import N_PLANT
from fricbench.trajectories import make_trajectory

TS = 1.0e-3
KP, KV = 160.0, 240.0
# EMPS's law: u = kv kp (x_r - x) - kv (x[k] - x[k-2]) / (2 ts)
C = [-KV * KP - KV / (2 * TS), 0.0, KV / (2 * TS)]


def _axis(**friction: float) -> Axis:
    return Axis.from_dict({
        "controller": {"ts": TS, "n_substeps": 2, "kt": 35.0, "i_max": 10.0, "law": "linear",
                       "law_reference": [KV * KP, 0.0, 0.0], "law_position": C},
        "mechanics": {"mass": 95.0, "damping": 200.0},
        "friction": {"id": "coulomb", "fc": friction.get("fc", 20.0)}})


def test_kernel_law_is_the_diagnosis_law_bit_for_bit() -> None:
    axis = _axis()
    ref = make_trajectory("m_serial", ts=TS)
    res = simulate(axis, ref)
    y, u = linear_law.simulate_one(
        axis.pack()[:N_PLANT], np.zeros(0), np.array(C), KV * KP * ref.x, ref.t, TS, n_sub=2,
        x0=ref.x[0], v0=ref.v[0], u_init=np.zeros(0),
        y_init=ref.x[0] - ref.v[0] * TS * np.arange(1, 4))
    np.testing.assert_array_equal(res.x, y)
    np.testing.assert_array_equal(res.u, 35.0 * u)


def test_law_without_friction_matches_python_control() -> None:
    """Oracle: with friction off the kernel runs closed_loop(axis) (n_substeps 1)."""
    axis = Axis.from_dict({
        "controller": {"ts": TS, "n_substeps": 1, "kt": 35.0, "i_max": 1e6, "law": "linear",
                       "law_reference": [KV * KP, 5.0, 0.5], "law_position": C,
                       "law_recursion": [0.3], "law_reference_history": [2.0, -1.0]},
        "mechanics": {"mass": 95.0, "damping": 200.0}}).without_friction()
    ref = make_trajectory("s_curve", ts=TS)
    res = simulate(axis, ref)
    sys = closed_loop(axis)
    u = np.zeros((5, ref.n_samples))
    u[0], u[1], u[2] = ref.x, ref.v, ref.a
    x0 = np.zeros(sys.nstates)
    x0[sys.find_state("x")] = ref.x[0]
    for j in range(1, 3):
        x0[sys.find_state(f"controller_x[k-{j}]")] = ref.x[0] - j * TS * ref.v[0]
    x0[sys.find_state("v")] = ref.v[0]
    for m in range(1, 3):
        x0[sys.find_state(f"controller_x_ref[k-{m}]")] = ref.x[0] - m * TS * ref.v[0]
    lin = control.forced_response(sys, T=ref.t, U=u, X0=x0).outputs
    # the kernel's trapezoidal position vs the exact ZOH sample: one substep of 1 ms
    assert np.max(np.abs(res.x - lin)) < 1e-3 * np.max(np.abs(ref.x))


def test_unstable_law_is_refused() -> None:
    with pytest.raises(ValueError, match="law is unstable"):
        Axis.from_dict({"controller": {"law": "linear", "law_reference": [0.0, 0.0, 0.0],
                                       "law_position": [1e6]}})


@pytest.mark.parametrize(("kw", "match"), [
    ({"law": "pid"}, "law='pid'"),
    ({"law": "linear", "law_reference": [1.0], "law_position": [-1.0]}, "law_reference"),
    ({"law": "linear", "law_reference": [1.0, 0, 0], "law_position": []}, "law_position"),
    ({"law": "linear", "law_reference": [1.0, 0, 0], "law_position": [-1.0],
      "law_recursion": [0.1] * 5}, "law_recursion"),
    ({"law_position": [1.0]}, "law='cascade'"),
    ({"law": "linear", "law_reference": [float("nan"), 0, 0], "law_position": [-1.0]},
     r"law_reference\[0\]"),
])
def test_bad_law_parameters(kw: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        ControllerParams(**kw)


def test_the_tally_counts_what_is_simulated_inside_it_only() -> None:
    """Rows, samples and plant steps of every simulate_batch call inside the block (a batch of
    three rows and a single row), in every open tally, and nothing outside."""
    axis = _axis()
    ref = make_trajectory("m_serial", ts=TS)
    row = axis.pack()[:N_PLANT]
    kw = dict(n_sub=2, x0=ref.x[0], v0=ref.v[0], u_init=np.zeros((3, 0)),
              y_init=ref.x[0] - ref.v[0] * TS * np.arange(1, 4))
    n = ref.t.shape[0]
    with linear_law.tally_simulations() as outer:
        linear_law.simulate_batch(np.tile(row, (3, 1)), np.zeros((3, 0)),
                                  np.tile(C, (3, 1)), KV * KP * ref.x, ref.t, TS, **kw)
        with linear_law.tally_simulations() as inner:
            linear_law.simulate_one(row, np.zeros(0), np.array(C), KV * KP * ref.x, ref.t, TS,
                                    **{**kw, "u_init": np.zeros(0)})
    linear_law.simulate_one(row, np.zeros(0), np.array(C), KV * KP * ref.x, ref.t, TS,
                            **{**kw, "u_init": np.zeros(0)})
    assert (outer.calls, outer.rows, outer.samples, outer.substeps) == (2, 4, 4 * n, 8 * n)
    assert (inner.calls, inner.rows, inner.samples, inner.substeps) == (1, 1, n, 2 * n)
    # two open tallies with the same counts: each closes its own
    with linear_law.tally_simulations() as first:
        with linear_law.tally_simulations():
            pass
        linear_law.simulate_one(row, np.zeros(0), np.array(C), KV * KP * ref.x, ref.t, TS,
                                **{**kw, "u_init": np.zeros(0)})
    assert first.rows == 1
