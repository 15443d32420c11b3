"""The diagnosis's view of the plant: names for the entries it fits, and the loop simulator.

The diagnosis predicts the measured position from the reference alone, through a grey-box loop
of an identified linear controller and the axis plant::

    u[k]   = sum_i a_i u[k-i] + r[k] + sum_j c_j y_fb[k-j] + w[k]      (linear controller, ARX)
    M dv/dt = u - B v - F_eff(x, v)                                   (the plant, ZOH on u)
    y[k]   = play_b(x(t_k)) + d(t_k)                                  (logged position)

(``d``: the thermal drift, of time or of the heating by the motor's motion.)

Both halves live in :mod:`fricbench.axis`: the plant (:mod:`fricbench.axis.plant`, the same
code the environments run) and the linear-law driver (:mod:`fricbench.axis.linear_law`). This
module only names the plant entries the effects of :mod:`fricbench.sysid.diagnose.effects` fit
and sets the plant up the diagnosis's way: a unit force gain (the effort is the force, or an
acceleration for a unit mass), no actuator limit unless the logged effort clips (``I_IMAX``),
feedback on the motor side.

Units: any consistent set. With a measured effort, forces are in the effort's unit (N when it is
a force) and ``M`` in that unit per m/s^2; without one the mass is normalised to 1 and every
force is an acceleration (m/s^2).
"""

from __future__ import annotations

import numpy as np

from fricbench.axis import plant as PL
from fricbench.axis.linear_law import simulate_batch, simulate_one
from fricbench.axis.plant import N_PLANT, PLANT_NAMES, sliding_force

__all__ = ["N_PLANT", "PLANT_NAMES", "simulate_batch", "simulate_one", "default_plant",
           "sliding_force", "from_legacy_row", "LEGACY_N_PLANT",
           "I_M", "I_B", "I_FC", "I_DFC", "I_DB", "I_FS", "I_VS", "I_OFF", "I_COGA", "I_COGB",
           "I_COGP", "I_PDG", "I_PDA", "I_PDB", "I_PDP", "I_XC", "I_BL", "I_THA", "I_THT", "I_THV",
           "I_IMAX", "I_DELAY",
           "I_CR", "I_CF", "I_CZ", "I_MEAS_TABLE", "I_LOG_MOTOR", "I_BL_LOAD",
           "I_COMP_LOAD", "I_COMP_B_MOTOR", "I_COGH2A", "I_COGH2B", "I_COGH3A", "I_COGH3B",
           "I_THS", "I_THX0"]

# -- the plant entries the diagnosis fits (indices into the plant row) --------------------------
I_M, I_B, I_FC, I_DFC, I_DB = PL.M, PL.B, PL.FC, PL.DFC, PL.DB
I_FS, I_VS, I_OFF = PL.FS_EXCESS, PL.VS, PL.OFFSET
I_COGA, I_COGB, I_COGP = PL.COG_SIN, PL.COG_COS, PL.COG_PERIOD
I_COGH2A, I_COGH2B, I_COGH3A, I_COGH3B = PL.COG_H2_SIN, PL.COG_H2_COS, PL.COG_H3_SIN, PL.COG_H3_COS
I_PDG, I_PDA, I_PDB, I_PDP, I_XC = PL.PD_GRAD, PL.PD_SIN, PL.PD_COS, PL.PD_PERIOD, PL.PD_CENTER
I_BL, I_THA, I_THT, I_THV = PL.BACKLASH, PL.TH_AMP, PL.TH_TAU, PL.TH_VHEAT
I_THS, I_THX0 = PL.TH_STRAIN, PL.TH_X0
I_IMAX, I_DELAY = PL.IMAX, PL.DELAY
I_BL_LOAD = PL.BL_LOAD
I_COMP_LOAD = PL.COMP_LOAD
I_COMP_B_MOTOR = PL.COMP_B_MOTOR
I_CR, I_CF, I_CZ = PL.COMP_RATIO, PL.COMP_FREQ, PL.COMP_ZETA
I_MEAS_TABLE, I_LOG_MOTOR = PL.MEAS_TABLE, PL.LOG_MOTOR

# the 19-entry row of grey-box files written before the plant was shared with the axis
_LEGACY = (I_M, I_B, I_FC, I_DFC, I_DB, I_FS, I_VS, I_OFF, I_COGA, I_COGB, I_COGP, I_PDG, I_PDA,
           I_PDB, I_PDP, I_XC, I_BL, I_THA, I_THT)
LEGACY_N_PLANT = len(_LEGACY)


def default_plant(mass: float = 1.0, damping: float = 0.0) -> np.ndarray:
    """Plant row with every effect off (periods and time constants at harmless values)."""
    return PL.default_row(mass, damping)


def from_legacy_row(row: np.ndarray) -> np.ndarray:
    """A plant row from the 19-entry layout of earlier grey-box files."""
    p = default_plant()
    p[list(_LEGACY)] = np.asarray(row, dtype=float)
    return p
