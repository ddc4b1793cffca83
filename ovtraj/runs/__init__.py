"""DoE runs of the mission chain and their Parquet run store; a plan's stored
Monte Carlo (:mod:`ovtraj.runs.plan_monte_carlo`, a study of the one Monte Carlo driver)
and a Monte Carlo's batches on the library's pools (:mod:`ovtraj.runs.monte_carlo_pool`)."""

from ovtraj.mission.design_space import latin_hypercube
from ovtraj.runs.execute import evaluate_batch, prepare_run, replay, run_doe
from ovtraj.runs.ids import run_id
from ovtraj.runs.store import Run, RunStore, StoreError

__all__ = [
    "Run",
    "RunStore",
    "StoreError",
    "evaluate_batch",
    "latin_hypercube",
    "prepare_run",
    "replay",
    "run_doe",
    "run_id",
]
