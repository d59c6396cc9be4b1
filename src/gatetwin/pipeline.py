"""Former home of the ``gatetwin run`` orchestration, kept so that existing scripts import.

The orchestration is :mod:`gatetwin.run` (``gatetwin.run.pipeline``); the bundled data are
located by :mod:`gatetwin.bundled`.
"""

from gatetwin.bundled import bundled_records_dir
from gatetwin.run.pipeline import STAGES, PipelineContext, PipelineStage, run_pipeline

__all__ = ["STAGES", "PipelineContext", "PipelineStage", "bundled_records_dir", "run_pipeline"]
