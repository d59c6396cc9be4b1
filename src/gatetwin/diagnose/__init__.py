"""Diagnosis: where a twin and the measurements disagree, which physical effect is missing,
and how much adding it (as an effect block of :mod:`gatetwin.plant.effects`) closes the gap.

The stages, one module each, plain functions on frozen objects:

* :mod:`~gatetwin.diagnose.data` -- the record as the diagnosis reads it (commanded opening,
  moves, fitted / held-out split);
* :mod:`~gatetwin.diagnose.grid_sim` -- the plant rendered on the record's uniform grid
  (numba; equal to the reference simulation to round-off), for fitting;
* :mod:`~gatetwin.diagnose.baseline` -- the baseline (model file, or identified from the
  record);
* :mod:`~gatetwin.diagnose.noise` -- noise floor, residual windows and regions;
* :mod:`~gatetwin.diagnose.signatures` -- what each effect leaves in the residual;
* :mod:`~gatetwin.diagnose.candidates` -- the candidate library, one module per effect;
* :mod:`~gatetwin.diagnose.fitting` / :mod:`~gatetwin.diagnose.select` -- joint fits, score
  and choice;
* :mod:`~gatetwin.diagnose.workflow` -- :func:`diagnose_record`; its model file, FMUs and
  figure are written by :mod:`~gatetwin.diagnose.artifacts` and
  :mod:`~gatetwin.diagnose.plots`.
"""

from gatetwin.diagnose.workflow import DiagnosisSettings, diagnose_record

__all__ = ["DiagnosisSettings", "diagnose_record"]
