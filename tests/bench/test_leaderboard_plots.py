"""The leaderboard's error-trace plot: every trace visible, the legend off the data."""

from __future__ import annotations

import numpy as np
from matplotlib.colors import to_rgba

from fricbench.bench.leaderboard import _trace_figure
from fricbench.bench.runner import EpisodeRecord

PAPER = "fricbench/PaperAxis-v0"
# the leaderboard's eleven, with maxima in um as on PaperAxis-v0 / m_serial
MAXIMA = {"none": 21.3, "ekf": 7.6, "friction-ff": 14.7, "greybox-precomp": 4.2, "ilc": 1.1,
          "kalman": 9.2, "rl-ppo": 7.9, "rl-residual": 7.4, "rl-sac": 8.1,
          "tf-lstm-precomp": 14.2, "tf-precomp": 18.6}


def _records() -> list[EpisodeRecord]:
    t = np.linspace(0.0, 2.0, 2001)
    return [EpisodeRecord(PAPER, comp, "m_serial", 0, max_error=m * 1e-6, trace_t=t,
                          trace_error=m * 1e-6 * np.sin(40.0 * t + i))
            for i, (comp, m) in enumerate(MAXIMA.items())]


def test_every_trace_has_its_own_style_and_the_smaller_errors_lie_on_top() -> None:
    fig = _trace_figure(PAPER, "m_serial", _records())
    (ax,) = fig.axes
    lines = {str(ln.get_label()).split(" (")[0]: ln for ln in ax.get_lines()}
    assert set(lines) == set(MAXIMA)
    styles = {(to_rgba(ln.get_color()), str(ln.get_linestyle())) for ln in lines.values()}
    assert len(styles) == len(MAXIMA)
    # the baseline lowest, then by decreasing maximum error: ilc (1.1 um) on top of kalman
    order = sorted(MAXIMA, key=lambda c: lines[c].get_zorder())
    assert order[0] == "none"
    assert order[1:] == sorted(set(MAXIMA) - {"none"}, key=lambda c: -MAXIMA[c])
    assert lines["ilc"].get_zorder() > lines["kalman"].get_zorder()
    assert ax.get_xlabel() == "time [s]" and ax.get_ylabel() == "tracking error [um]"


def test_the_legend_lies_outside_the_axes() -> None:
    fig = _trace_figure(PAPER, "m_serial", _records())
    (ax,) = fig.axes
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    legend = ax.get_legend()
    assert legend is not None and len(legend.get_texts()) == len(MAXIMA)
    box, frame = legend.get_window_extent(renderer), ax.get_window_extent(renderer)
    assert box.x0 >= frame.x1  # right of the data, not over a spike
    # and inside the figure
    assert box.x1 <= fig.bbox.x1 + 0.5
