"""``fricbench diagnose``: residual -> missing effect -> refit -> error before and after.

From a run (reference, measured position, optional effort) the diagnosis fits a linear
closed-loop model, tests the residual against a library of physical effects
(:mod:`~fricbench.sysid.diagnose.effects`), adds the effect that removes the most error on
held-out data, refits everything with it, and repeats until nothing significant is left.

Modules, in the order of the workflow:

* :mod:`~fricbench.sysid.diagnose.signals` - filtered derivatives, decimation, folds, the
  noise floor, spatial periods;
* :mod:`~fricbench.sysid.diagnose.prepared` - everything derived once from a run;
* :mod:`~fricbench.sysid.diagnose.leastsq` - the least-squares solves, on scipy's solvers;
* :mod:`~fricbench.sysid.diagnose.controllers` - cascade and identified (ARX) control laws;
* :mod:`~fricbench.sysid.diagnose.closed_loop` - the plant entries the effects fit; the grey box
  runs on the axis's own plant (:mod:`fricbench.axis.plant`) under a linear law
  (:mod:`fricbench.axis.linear_law`), the same code as the environments;
* :mod:`~fricbench.sysid.diagnose.effects` - the candidate effects;
* :mod:`~fricbench.sysid.diagnose.models` - the grey-box model and its two fits;
* :mod:`~fricbench.sysid.diagnose.baselines` - the linear starting models;
* :mod:`~fricbench.sysid.diagnose.equation_error` - a loop and its friction by linear least
  squares on the measured motion (starts of the output-error fits);
* :mod:`~fricbench.sysid.diagnose.search` - forward selection on held-out data;
* :mod:`~fricbench.sysid.diagnose.diagnosis` - the workflow (:func:`diagnose`);
* :mod:`~fricbench.sysid.diagnose.report` - JSON and plots;
* :mod:`~fricbench.sysid.diagnose.command` - the command line.
"""

from fricbench.sysid.diagnose.diagnosis import DiagnosisResult, diagnose
from fricbench.sysid.diagnose.effects import EFFECT_NAMES
from fricbench.sysid.diagnose.search import SearchSettings

__all__ = ["diagnose", "DiagnosisResult", "SearchSettings", "EFFECT_NAMES"]
