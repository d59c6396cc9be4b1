"""Validation of plant FMUs against measured records (the fmpy harness).

Drive an FMI 2.0 co-simulation FMU with a record's measured gate opening and discharge,
compare its free-running level output with the measured level, apply the caller's
thresholds, and render the findings as JSON, JUnit XML and plots.

* :mod:`~gatetwin.validation.fmu_inspect` -- whether a file is an FMU the harness can run;
* :mod:`~gatetwin.validation.fmu_runner` -- open, check and run an FMU through fmpy;
* :mod:`~gatetwin.validation.isolation` -- the same run in a child process, under a time limit,
  with the cause named when the FMU crashes, exits or hangs;
* :mod:`~gatetwin.validation.compare` -- free-run metrics, the noise floor's fit and FOPDT step
  comparison;
* :mod:`~gatetwin.validation.validity` -- the FMU's validity envelope and whether a record lies
  inside it;
* :mod:`~gatetwin.validation.thresholds` -- ``--fail-under`` / ``--fail-over`` limits;
* :mod:`~gatetwin.validation.harness` -- one FMU on many records, and the FMU × record matrix;
* :mod:`~gatetwin.validation.results` -- what that finds, per record and per FMU;
* :mod:`~gatetwin.validation.matrix` -- the matrix as flat cells and as a Markdown table;
* :mod:`~gatetwin.validation.outputs` -- JSON, JUnit and PNG rendering, atomic writing.

Exit-code policy of ``gatetwin validate``: 0 when everything passed, :data:`EXIT_FAILED`
(1) when a threshold, fmpy's static validation, the FMU's run (crash, exit, timeout,
output not finite) or (with ``--fail-outside-validity``) the validity envelope failed, 2 for
input it cannot validate.
"""

from gatetwin.errors import ValidationError
from gatetwin.validation.compare import (
    FreeRunMetrics,
    StepComparison,
    free_run_metrics,
    noise_floor_fit_percent,
)
from gatetwin.validation.fmu_runner import (
    CommunicationGrid,
    FmuInfo,
    communication_grid,
    inspect_fmu,
    static_findings,
)
from gatetwin.validation.harness import (
    VALIDITY_CHECK,
    FmuValidation,
    RecordValidation,
    matrix_cells,
    matrix_markdown,
    validate_fmu,
    validate_matrix,
)
from gatetwin.validation.outputs import (
    OutputPaths,
    junit_xml,
    outside_message,
    plot_record,
    validation_document,
    write_outputs,
)
from gatetwin.validation.thresholds import (
    HIGHER_IS_BETTER,
    LOWER_IS_BETTER,
    Check,
    Threshold,
    parse_thresholds,
)
from gatetwin.validation.validity import ValidityFinding, read_envelope, record_validity

#: Exit code of ``gatetwin validate`` when a threshold or the static validation failed.
EXIT_FAILED = 1

__all__ = [
    "EXIT_FAILED",
    "HIGHER_IS_BETTER",
    "LOWER_IS_BETTER",
    "Check",
    "CommunicationGrid",
    "FmuInfo",
    "FmuValidation",
    "FreeRunMetrics",
    "OutputPaths",
    "RecordValidation",
    "StepComparison",
    "Threshold",
    "VALIDITY_CHECK",
    "ValidationError",
    "ValidityFinding",
    "communication_grid",
    "free_run_metrics",
    "inspect_fmu",
    "junit_xml",
    "matrix_cells",
    "matrix_markdown",
    "noise_floor_fit_percent",
    "outside_message",
    "parse_thresholds",
    "plot_record",
    "read_envelope",
    "record_validity",
    "static_findings",
    "validate_fmu",
    "validate_matrix",
    "validation_document",
    "write_outputs",
]
