"""``gatetwin run``: the whole job on a records folder, stage by stage, into one output folder.

:mod:`~gatetwin.run.pipeline` (the stages' order, the output folder's life cycle),
:mod:`~gatetwin.run.stages` (validation matrix, family comparison, MPC demo, diagnosis,
report), :mod:`~gatetwin.run.outdir` (who owns ``--out``), :mod:`~gatetwin.run.tables` and
:mod:`~gatetwin.run.figures` (the paper's tables and figures); :mod:`~gatetwin.run.swmm_demo`
(``gatetwin swmm demo``: the same chain on a gate of an EPA SWMM canal). Nothing in the
libraries imports this package.
"""

from gatetwin.run.pipeline import STAGES, PipelineContext, PipelineStage, run_pipeline

__all__ = ["STAGES", "PipelineContext", "PipelineStage", "run_pipeline"]
