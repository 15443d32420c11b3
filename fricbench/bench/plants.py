"""The machine each benchmark seed runs on: moved to :mod:`fricbench.axis.variation`.

The plant draw lives with the axis, below the compensators that train on drawn plants; this
module re-exports it under the name the leaderboard tables (their "Plants" line, which the
committed tables must reproduce word for word) and the shipped rl-residual policy cite.
"""

from fricbench.axis.variation import (
    BENCH_VARIATION,
    PLANT_SEED_TAG,
    PlantVariation,
    draw_plant,
    nominal_told,
)

__all__ = ["BENCH_VARIATION", "PLANT_SEED_TAG", "PlantVariation", "draw_plant", "nominal_told"]
