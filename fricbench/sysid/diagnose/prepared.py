"""Everything the fits derive once from a run: reference derivatives, filtered motion,
decimated columns, folds, the noise floor and the ranges that bound the parameters."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.controllers import LoopInputs
from fricbench.sysid.diagnose.settings import defaults
from fricbench.sysid.diagnose.signals import (
    NoiseFloor,
    Saturation,
    block_folds,
    choose_filter,
    decimate_columns,
    detect_saturation,
    filtered_derivatives,
    noise_floor,
)
from fricbench.sysid.io import RunData

__all__ = ["Prepared", "prepare", "substeps"]


def substeps(ts: float, n_loop: int = 1, max_step: float | None = None) -> int:
    """Plant substeps per loop period for a log sampled every ``ts`` seconds whose loop runs
    ``n_loop`` times per sample: enough for a step of at most ``max_step`` (s; default
    ``settings.loop_ts``, the drive's own loop period), and never fewer than
    ``settings.n_sub_min``."""
    if max_step is None:
        max_step = defaults().loop_ts
    loop_ts = float(ts) / max(int(n_loop), 1)
    # a sample time read from a time column carries rounding: 10.000001 steps are 10
    return max(defaults().n_sub_min, math.ceil(loop_ts / max_step - 1e-6))


@dataclass
class Prepared:
    """Derived signals of one run (see :func:`prepare`).

    Attributes
    ----------
    run : RunData
    inputs : LoopInputs
        Reference signals and initial state for simulations.
    x : ndarray
        Measured position, m.
    u : ndarray or None
        Measured effort.
    xf, vf, af : ndarray
        Filtered position (m), velocity (m/s), acceleration (m/s^2) at the full rate.
    decim : int
        Decimation factor of the inverse-dynamics regression.
    cutoff_hz : float
        Cut-off of the derivative filter, Hz.
    folds : ndarray of int
        Fold of each sample (0/1), contiguous blocks in turn.
    folds_dec : ndarray of int
        Fold of each decimated sample.
    noise : NoiseFloor
    stroke : float
        Range of the measured position, m.
    center : float
        Middle of that range, m.
    v_max : float
        Largest reference speed, m/s.
    n_sub : int
        Plant substeps per loop period of the simulations (see :func:`substeps`).
    sliding_dec : ndarray of bool
        Decimated rows away from rest and away from a saturated effort (the inverse dynamics
        is fitted on these).
    saturation : Saturation or None
        The clip level of the effort, when the effort saturates.
    filter_source : str
        How the derivative filter and decimation were chosen (``"stated"``, ``"default"``,
        ``"sensor resolution"``).
    x_load : ndarray or None
        A second, load-side position (a linear scale beside the motor encoder ``x``), m, when
        the run has one (``--load-position``).
    """

    run: RunData
    inputs: LoopInputs
    x: np.ndarray
    u: np.ndarray | None
    xf: np.ndarray
    vf: np.ndarray
    af: np.ndarray
    decim: int
    cutoff_hz: float
    folds: np.ndarray
    folds_dec: np.ndarray
    noise: NoiseFloor
    stroke: float
    center: float
    v_max: float
    n_sub: int = 2
    sliding_dec: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    saturation: Saturation | None = None
    filter_source: str = "default"
    x_load: np.ndarray | None = None
    _dec_cache: dict[object, np.ndarray] = field(default_factory=dict, repr=False)

    @property
    def ts(self) -> float:
        """Sample time, s."""
        return self.inputs.ts

    def with_loop(self, n_loop: int) -> Prepared:
        """The same run simulated with a loop ``n_loop`` times faster than the log (see
        :attr:`fricbench.sysid.diagnose.controllers.LoopInputs.n_loop`)."""
        if n_loop == self.inputs.n_loop:
            return self
        # the integration step is a time step: the substeps per logged sample are kept, spread
        # over the loop's periods (at least settings.n_sub_min each)
        per_sample = self.n_sub * self.inputs.n_loop
        return dataclasses.replace(
            self, inputs=dataclasses.replace(self.inputs, n_loop=n_loop),
            n_sub=max(defaults().n_sub_min, math.ceil(per_sample / n_loop)))

    @property
    def rotary(self) -> bool:
        """Positions are angles (the run's position unit is rad)."""
        return bool(self.run.units.get("position", "m") == "rad")

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.x.shape[0])

    @property
    def duration(self) -> float:
        """Length of the run, s."""
        return float(self.inputs.t[-1])

    def dec(self, key: object, column: np.ndarray | None = None) -> np.ndarray:
        """The decimated form of a full-rate column, cached under ``key``."""
        if key not in self._dec_cache:
            if column is None:
                raise KeyError(f"no decimated column cached under {key!r}")
            self._dec_cache[key] = decimate_columns(column, self.decim)
        return self._dec_cache[key]


def prepare(run: RunData, *, cutoff_hz: float | None = None, decim: int | None = None,
            n_sub: int | None = None, n_blocks: int = 20, quantum: float | None = None) -> Prepared:
    """Derive the signals of ``run`` used by the fits.

    Parameters
    ----------
    run : RunData
    cutoff_hz : float, optional
        Derivative filter cut-off, Hz. Default: chosen from the data by
        :func:`fricbench.sysid.diagnose.signals.choose_filter` (a tenth of the sampling rate,
        the EMPS IDIM-LS recipe, unless the sensor is too coarse for the motion's speed).
    decim : int, optional
        Decimation factor of the inverse-dynamics regression (default: from the data as well;
        10 with the recipe's filter).
    n_sub : int, optional
        Plant substeps per sample in simulations. Default: :func:`substeps` of the run's
        sample time.
    n_blocks : int
        Number of contiguous time blocks of the held-out folds.
    quantum : float, optional
        The position sensor's step (m or rad), when known; else detected from the data.

    Returns
    -------
    Prepared
    """
    ts = run.ts
    t = run.t - run.t[0]
    vr = np.gradient(run.x_ref, ts)
    ar = np.gradient(vr, ts)
    noise = noise_floor(run.x, run.x_ref, quantum)
    auto_fc, auto_decim, source = choose_filter(run.x, ts, noise)
    if cutoff_hz is not None or decim is not None:
        source = "stated"
    if cutoff_hz is None:
        cutoff_hz = auto_fc
    if decim is None:
        decim = auto_decim
    decim = int(max(1, min(decim, run.n_samples // 100)))
    xf, vf, af = filtered_derivatives(run.x, ts, cutoff_hz)
    sat = detect_saturation(run.u) if run.u is not None else None
    u0 = float(run.u[0]) if run.u is not None else float(ar[0])
    inputs = LoopInputs(t=t, ts=ts, xr=run.x_ref, vr=vr, ar=ar, x0=float(run.x[0]),
                        v0=float(vf[0]), u0=u0)
    folds = block_folds(run.n_samples, n_blocks)
    prep = Prepared(
        run=run, inputs=inputs, x=run.x, u=run.u, xf=xf, vf=vf, af=af, decim=decim,
        cutoff_hz=float(cutoff_hz), folds=folds, folds_dec=folds[::decim],
        noise=noise, stroke=float(np.ptp(run.x)),
        center=float(0.5 * (np.max(run.x) + np.min(run.x))), v_max=float(np.max(np.abs(vr))),
        n_sub=substeps(ts) if n_sub is None else int(n_sub), saturation=sat,
        filter_source=source, x_load=run.x_load,
    )
    # align the decimated folds with the decimated columns
    n_dec = prep.dec("ones", np.ones(run.n_samples)).shape[0]
    prep.folds_dec = prep.folds_dec[:n_dec]
    # rows of the inverse dynamics fitted: not at or near rest, where the friction force is
    # whatever holds the axis (set-valued) and no sliding law can predict it
    cfg = defaults()
    v_rest = max(cfg.rest_speed_share * prep.v_max, 1e-9)
    rest = prep.dec("rest", (np.abs(vf) < v_rest).astype(float))
    prep.sliding_dec = rest < cfg.rest_row_share
    n_sliding = np.count_nonzero(prep.sliding_dec)
    # an axis that sticks most of the run (a slow move under a large breakaway force) still
    # slides on enough rows; fitting its stuck rows would fit the integral's wind-up against
    # the static friction (a Stribeck run sliding on 16 % of its rows: effort error 83 % with
    # every row, 3 % and the true mass, damping and Coulomb level on the sliding ones).
    # Enough: the rule of thumb's rows per parameter of the first model fitted to the effort
    # (mass, damping, Coulomb level) in each fold of the inverse dynamics
    first_fit = (CL.I_M, CL.I_B, CL.I_FC)
    n_folds = int(np.unique(prep.folds_dec).size)
    if n_sliding < cfg.rows_per_parameter * len(first_fit) * n_folds:
        prep.sliding_dec = np.ones(n_dec, dtype=bool)
    if sat is not None:
        # a clipped effort is the drive's limit, not the force the law asked for: the rows it
        # touches (after the decimation filter's spread) stay out of the friction fit
        near = prep.dec("saturated", sat.mask.astype(float))
        prep.sliding_dec = prep.sliding_dec & (np.abs(near) < cfg.clipped_row_share)
    return prep
