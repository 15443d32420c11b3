"""The diagnosis' settings, in one place (python-control's ``config.defaults`` habit).

Every value the one criterion and the one search read is a field of :class:`DiagnoseSettings`,
with what it means and where its value came from. The method is stated in
``docs/diagnosis_method.md``.

The closed-loop search (:mod:`fricbench.sysid.diagnose.search`) still carries the thresholds it
grew case by case (its :class:`~fricbench.sysid.diagnose.search.SearchSettings` and module
constants); they move here, or go, as it is brought onto the criterion. The open-loop
diagnosis reads only these.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DiagnoseSettings", "DEFAULT_SETTINGS"]


@dataclass(frozen=True)
class DiagnoseSettings:
    """Settings of the criterion, the search and the reported uncertainty.

    Parameters
    ----------
    penalty : float
        Penalty per parameter added, in units of the criterion
        ``n_eff ln(SSE_heldout / n)``: Akaike's 2 (AIC; Akaike 1974). Not tuned.
    detection_sd : float
        An effect whose every size lies within this many standard deviations of zero is "not
        detected" and left out of the model: 2, the usual two-sided 95 % (a normal
        approximation of the estimate; Ljung 1999, section 9.6). Not tuned.
    folds : int
        Contiguous blocks of the run for the held-out error (each fitted on the others and
        simulated free over itself): 2, the fewest that hold one out, at 2 fits per
        candidate. With ``k`` blocks each fit sees ``(k - 1) / k`` of the run and the criterion
        more held-out blocks, at ``k`` fits per candidate: on EMPS's training run 4 blocks
        let the viscous asymmetry join (held-out 2.81 -> 2.00 mm) where 2 rejected every
        candidate, and the protocol's test error went from 6.84 to 7.63 mm. Not tuned; a
        change waits for a comparison on the simulators' open-loop runs, not on a test run.
    max_effects : int
        Most effects the forward selection adds beyond the base model: 3 (the open loop's
        library has 5 candidates; each step costs ``folds`` fits per candidate). A budget,
        not a threshold.
    max_lag_share : float
        The effective sample count (:func:`~fricbench.sysid.diagnose.criterion.
        effective_samples`) sums the residual's autocorrelation up to this share of its
        length at most: 0.1, beyond which the estimate of a correlation is mostly noise
        (Box & Jenkins' rule of thumb of lags up to a quarter, taken tighter). Not tuned.
    """

    penalty: float = 2.0
    detection_sd: float = 2.0
    folds: int = 2
    max_effects: int = 3
    max_lag_share: float = 0.1

    def __post_init__(self) -> None:
        if not self.penalty >= 0.0:
            raise ValueError(f"penalty={self.penalty!r}: expected a number >= 0")
        if not self.detection_sd >= 0.0:
            raise ValueError(f"detection_sd={self.detection_sd!r}: expected a number >= 0")
        if not (isinstance(self.folds, int) and self.folds >= 2):
            raise ValueError(f"folds={self.folds!r}: expected an integer >= 2 (one block "
                             "held out, at least one to fit on)")
        if not (isinstance(self.max_effects, int) and self.max_effects >= 0):
            raise ValueError(f"max_effects={self.max_effects!r}: expected an integer >= 0")
        if not 0.0 < self.max_lag_share <= 0.5:
            raise ValueError(f"max_lag_share={self.max_lag_share!r}: expected a share in "
                             "(0, 0.5]")


DEFAULT_SETTINGS = DiagnoseSettings()
"""The settings every diagnosis uses unless given others."""
