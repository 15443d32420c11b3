"""Writing a diagnosis: the JSON report and the residual plots, each written atomically.

Every file is first written to a temporary file in the target directory and then moved over
the target with :func:`os.replace`, so a reader never sees a half-written report and an
interrupted run leaves the previous one intact.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from fricbench._atomic import atomic_write_via
from fricbench.run_events import motion_sign, sign_reversals
from fricbench.sysid.diagnose import closed_loop as CL
from fricbench.sysid.diagnose.diagnosis import DiagnosisResult
from fricbench.sysid.diagnose.models import InverseDynamics
from fricbench.sysid.diagnose.settings import defaults

__all__ = ["write_json", "write_report", "jsonable", "PLOTS"]

PLOTS = ("residual_time.png", "residual_velocity.png", "residual_position.png",
         "residual_reversals.png", "steps.png")


def jsonable(obj: object) -> object:
    """``obj`` with numpy scalars and arrays as Python values and NaN/inf as None."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    return obj


def write_json(path: str, data: dict[str, object]) -> None:
    """Write ``data`` as indented JSON to ``path`` atomically."""
    text = json.dumps(jsonable(data), indent=2, allow_nan=False) + "\n"

    def _write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    atomic_write_via(path, _write)


def _save(fig: object, path: str) -> None:
    import matplotlib.pyplot as plt

    atomic_write_via(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))  # type: ignore
    plt.close(fig)  # type: ignore[arg-type]


def write_report(result: DiagnosisResult, directory: str) -> list[str]:
    """Write ``report.json`` and the residual plots of ``result`` into ``directory``.

    Plots (before = linear model, after = final model): the position residual against time,
    velocity and position (with its spatial spectrum, where cogging shows as a line), and
    aligned on velocity reversals (where backlash shows as a step); with an effort, the effort
    residual of the inverse dynamics beside them; the error after each step.

    Returns
    -------
    list of str
        Paths written.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    os.makedirs(directory, exist_ok=True)
    paths = []
    path = os.path.join(directory, "report.json")
    write_json(path, result.to_dict())
    paths.append(path)

    prep = result.prep
    t = prep.inputs.t
    r_before = prep.x - result.train.y_before
    r_after = prep.x - result.train.y_after
    pu = result.run.logged_unit
    um, ul = pu.per_si, pu.display  # residuals in um, mrad or deg
    vk, vl = pu.velocity_per_si, pu.velocity_display
    xk, xl = pu.coarse_per_si, pu.coarse_display
    effort = None
    if prep.u is not None and result.mode == "effort":
        idim = InverseDynamics(prep, prep.u, delay=int(result.final.plant[CL.I_DELAY]))
        effort = (idim.u_dec - idim.predict(result.linear.plant),
                  idim.u_dec - idim.predict(result.final.plant), idim)
    colors = {"before": "tab:red", "after": "tab:blue"}

    # -- against time
    n_rows = 2 if effort is not None else 1
    fig, axes = plt.subplots(n_rows, 1, figsize=(9, 3.2 * n_rows), squeeze=False)
    ax = axes[0, 0]
    ax.plot(t, r_before * um, lw=0.6, color=colors["before"], label="linear model")
    ax.plot(t, r_after * um, lw=0.6, color=colors["after"], label="with effects")
    ax.set_ylabel(f"position residual ({ul})")
    ax.set_xlabel("time (s)")
    ax.legend(loc="upper right")
    ax.set_title("measured minus free-run predicted position")
    if effort is not None:
        td = t[:: prep.decim][: effort[0].shape[0]]
        ax = axes[1, 0]
        ax.plot(td, effort[0], lw=0.6, color=colors["before"], label="linear")
        ax.plot(td, effort[1], lw=0.6, color=colors["after"], label="with effects")
        ax.set_ylabel(f"effort residual ({result.force_unit})")
        ax.set_xlabel("time (s)")
        ax.legend(loc="upper right")
    fig.tight_layout()
    path = os.path.join(directory, "residual_time.png")
    _save(fig, path)
    paths.append(path)

    # -- against velocity
    fig, axes = plt.subplots(1, n_rows, figsize=(5 * n_rows, 3.6), squeeze=False)
    v = prep.vf
    step = max(1, prep.n // 20000)
    ax = axes[0, 0]
    ax.plot(v[::step] * vk, r_before[::step] * um, ".", ms=1, color=colors["before"],
            label="linear model")
    ax.plot(v[::step] * vk, r_after[::step] * um, ".", ms=1, color=colors["after"],
            label="with effects")
    ax.set_xlabel(f"velocity ({vl})")
    ax.set_ylabel(f"position residual ({ul})")
    ax.legend(loc="upper right", markerscale=8)
    if effort is not None:
        ax = axes[0, 1]
        vd = effort[2].v_dec
        ax.plot(vd * vk, effort[0], ".", ms=1.5, color=colors["before"], label="linear")
        ax.plot(vd * vk, effort[1], ".", ms=1.5, color=colors["after"], label="with effects")
        ax.set_xlabel(f"velocity ({vl})")
        ax.set_ylabel(f"effort residual ({result.force_unit})")
        ax.legend(loc="upper right", markerscale=6)
    fig.tight_layout()
    path = os.path.join(directory, "residual_velocity.png")
    _save(fig, path)
    paths.append(path)

    # -- against position, with the spatial spectrum
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    x = prep.xf
    # the samples that slide (settings.rest_speed_share), as the diagnosis's own
    sliding = defaults().rest_speed_share * max(prep.v_max, 1e-12)
    moving = np.abs(v) > sliding
    if effort is not None:
        xs, res_b, res_a = effort[2].x_dec, effort[0], effort[1]
        mv = np.abs(effort[2].v_dec) > sliding
        label, unit = "effort residual", result.force_unit
    else:
        xs, res_b, res_a, mv = x, r_before * um, r_after * um, moving
        label, unit = "position residual", ul
    ax = axes[0]
    ax.plot(xs[mv][::step] * xk, res_b[mv][::step], ".", ms=1, color=colors["before"],
            label="linear model")
    ax.plot(xs[mv][::step] * xk, res_a[mv][::step], ".", ms=1, color=colors["after"],
            label="with effects")
    ax.set_xlabel(f"position ({xl})")
    ax.set_ylabel(f"{label} ({unit})")
    ax.legend(loc="upper right", markerscale=8)
    ax = axes[1]
    # only samples closer together than a spectrum bin (else the sampling pattern itself
    # shows up as lines)
    width = max(prep.stroke, 1e-9) / 500.0
    dt = prep.ts * (prep.decim if effort is not None else 1)
    vv = effort[2].v_dec if effort is not None else v
    slow = mv & (np.abs(vv) * dt <= width)
    # the mean of each stretch of one direction is removed first: friction steps would
    # otherwise swamp the spectrum
    seg = np.cumsum(np.r_[0, np.diff(np.sign(vv)) != 0])
    for res, key in ((res_b, "before"), (res_a, "after")):
        means = np.bincount(seg, weights=res) / np.maximum(np.bincount(seg), 1)
        f, pw = _spatial_spectrum(xs[slow], (res - means[seg])[slow], width)
        if f.size:
            ax.semilogy(f / xk, pw, lw=0.8, color=colors[key],
                        label="linear model" if key == "before" else "with effects")
    ax.set_xlabel(f"spatial frequency (1/{xl})")
    ax.set_ylabel("power")
    if not ax.get_legend_handles_labels()[0]:
        ax.text(0.5, 0.5, "too few slow samples", ha="center", transform=ax.transAxes)
    ax.set_title(f"spectrum against position, |v| < {width / dt * vk:.3g} {vl}\n"
                 "(stroke means removed; a periodic force: a line)", fontsize=9)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right")
    fig.tight_layout()
    path = os.path.join(directory, "residual_position.png")
    _save(fig, path)
    paths.append(path)

    # -- aligned on reversals
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    before_w, after_w, lags = _aligned(r_before, r_after, prep.inputs.vr, prep.ts)
    for seg in before_w:
        ax.plot(lags * 1e3, seg * um, lw=0.5, color=colors["before"], alpha=0.5)
    for seg in after_w:
        ax.plot(lags * 1e3, seg * um, lw=0.5, color=colors["after"], alpha=0.5)
    ax.plot([], [], color=colors["before"], label="linear model")
    ax.plot([], [], color=colors["after"], label="with effects")
    ax.axvline(0.0, color="k", lw=0.5)
    ax.set_xlabel("time from a reference reversal (ms); sign flipped for reversals to -")
    ax.set_ylabel(f"position residual ({ul})")
    ax.set_title("residual at reversals (backlash: a step, friction: a spike)")
    ax.legend(loc="upper right")
    fig.tight_layout()
    path = os.path.join(directory, "residual_reversals.png")
    _save(fig, path)
    paths.append(path)

    # -- error after each step
    steps = result.search.steps
    labels = ["linear"] + [s.effect or "" for s in steps[1:]]
    fig, axes = plt.subplots(1, n_rows, figsize=(4.5 * n_rows + 1, 3.6), squeeze=False)
    ax = axes[0, 0]
    ax.bar(range(len(steps)), [s.position_rms * um for s in steps], color="tab:blue")
    ax.axhline(result.prediction_floor * um, color="k", ls="--", lw=0.8, label="noise floor")
    ax.set_xticks(range(len(steps)), labels, rotation=30, ha="right", fontsize=8)
    ax.set_ylabel(f"position rms error ({ul})")
    ax.legend(loc="upper right")
    if effort is not None:
        ax = axes[0, 1]
        ax.bar(range(len(steps)), [s.effort_relerr_pct or 0.0 for s in steps],
               color="tab:orange")
        ax.set_xticks(range(len(steps)), labels, rotation=30, ha="right", fontsize=8)
        ax.set_ylabel("effort relative error (%)")
    fig.tight_layout()
    path = os.path.join(directory, "steps.png")
    _save(fig, path)
    paths.append(path)
    return paths


def _spatial_spectrum(x: np.ndarray, r: np.ndarray, width: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Power of ``r`` against spatial frequency (1/m), binned on a uniform position grid."""
    if x.size < 64:
        return np.zeros(0), np.zeros(0)
    span = float(np.ptp(x))
    n_bins = max(8, int(span / width) + 1)
    idx = np.minimum(((x - x.min()) / width).astype(np.int64), n_bins - 1)
    sums = np.bincount(idx, weights=r - r.mean(), minlength=n_bins)
    counts = np.bincount(idx, minlength=n_bins)
    series = np.where(counts > 0, sums / np.maximum(counts, 1), 0.0)
    power = np.abs(np.fft.rfft(series)) ** 2
    freqs = np.fft.rfftfreq(n_bins, width)
    return freqs[1:], power[1:] + 1e-300


def _aligned(rb: np.ndarray, ra: np.ndarray, vr: np.ndarray, ts: float, before: float = 0.05,
             after: float = 0.3) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """Residual windows around each reversal of the reference velocity, signed so that every
    window shows a reversal towards positive velocity."""
    s = np.sign(vr)
    lags = np.arange(-int(before / ts), int(after / ts)) * ts
    wb: list[np.ndarray] = []
    wa: list[np.ndarray] = []
    change = sign_reversals(motion_sign(vr, 0.0))
    i0, i1 = int(before / ts), int(after / ts)
    for i in change[:200]:
        if i - i0 < 0 or i + i1 > rb.shape[0]:
            continue
        sign = s[i]
        wb.append(sign * (rb[i - i0:i + i1] - rb[i - i0]))
        wa.append(sign * (ra[i - i0:i + i1] - ra[i - i0]))
    return wb, wa, lags
