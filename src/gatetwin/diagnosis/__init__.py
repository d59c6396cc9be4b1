"""Diagnosis: where a twin and the measurements disagree, which physical effect is missing,
and how much adding it (as an effect block of :mod:`gatetwin.plant.effects`) closes the gap.

The stages, one module each, plain functions on frozen objects:

* :mod:`~gatetwin.diagnosis.data` -- the record as the diagnosis reads it (commanded opening,
  moves, fitted / held-out split);
* :mod:`~gatetwin.diagnosis.grid_sim` -- the plant rendered on the record's uniform grid
  (numba; equal to the reference simulation to round-off), for fitting;
* :mod:`~gatetwin.diagnosis.baseline` -- the baseline (model file, or identified from the
  record);
* :mod:`~gatetwin.diagnosis.noise` -- noise floor, residual windows and regions;
* :mod:`~gatetwin.diagnosis.signatures` -- what each effect leaves in the residual;
* :mod:`~gatetwin.diagnosis.candidates` -- the candidate library, one module per effect;
* :mod:`~gatetwin.diagnosis.fitting` / :mod:`~gatetwin.diagnosis.select` -- joint fits, score
  and choice;
* :mod:`~gatetwin.diagnosis.workflow` -- :func:`diagnose_record`; its model file, FMUs and
  figure are written by :mod:`~gatetwin.diagnosis.artifacts` and
  :mod:`~gatetwin.diagnosis.plots`.
"""

from gatetwin.diagnosis.workflow import DiagnosisSettings, diagnose_record

__all__ = ["DiagnosisSettings", "diagnose_record"]
