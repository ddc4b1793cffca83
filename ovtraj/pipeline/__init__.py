"""The surrogate pipeline over a DoE run (SPEC steps 5-6; docs/optimize.md).

``data``: a run's training data; ``steps``: the surrogate fit and the surrogate
front, each stored in the run and reused by content hash; ``loop``: verification of
front points with the real chain, infill and the verified front; ``pick``: choosing
a point of the front for the mission plan.
"""

from ovtraj.pipeline.data import TrainingData, pipeline_doe_run, run_scenario, training_data
from ovtraj.pipeline.loop import PipelineResult, PipelineSteps, run_pipeline
from ovtraj.pipeline.pick import Pick, pick_front_point
from ovtraj.pipeline.steps import (
    FitOutcome,
    FrontOutcome,
    OptimiserStopped,
    PipelineError,
    View,
    draw_views,
    fit_step,
    front_step,
    start_drawing,
)

__all__ = [
    "FitOutcome",
    "FrontOutcome",
    "OptimiserStopped",
    "Pick",
    "PipelineError",
    "PipelineResult",
    "PipelineSteps",
    "TrainingData",
    "View",
    "draw_views",
    "fit_step",
    "front_step",
    "pick_front_point",
    "pipeline_doe_run",
    "run_pipeline",
    "run_scenario",
    "start_drawing",
    "training_data",
]
