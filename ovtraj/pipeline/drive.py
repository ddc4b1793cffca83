"""The whole mission pipeline, once: the one driver behind ``ovtraj pipeline`` and the
mission flow.

1. the DoE run: created, reopened or extended (:func:`.data.pipeline_doe_run`);
2. its batches evaluated by a :class:`BatchExecutor`;
3. the loop: fit, front, verify, infill (:func:`.loop.run_pipeline`), each infill run's
   batches on the same executor;
4. the executor stopped, then the pick of the verified front and its mission plan
   (:func:`.planning.write_mission_plan`).

Where the batches run is the executor's business, nothing else: the library's pools
(:class:`ovtraj.runs.execute.PoolBatches`: serial, threads, processes, Dask) or Prefect's
task runners (``flows/pipeline.py``: each batch a cached task). Everything else is the
same code, so the two give the same store for the same inputs (tests/test_pipeline_flow.py
compares them file by file).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from concurrent.futures import Executor
from contextlib import nullcontext
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol

from ovtraj.config import Scenario
from ovtraj.launch.launch_fit import LaunchFit
from ovtraj.pipeline.data import pipeline_doe_run
from ovtraj.pipeline.loop import PipelineResult, PipelineSteps, run_pipeline
from ovtraj.pipeline.pick import Pick
from ovtraj.pipeline.planning import write_mission_plan
from ovtraj.pipeline.report import stop_explanation
from ovtraj.pipeline.steps import (
    PipelineError,
    draw_views,
    fit_step,
    fitting_pool,
    front_step,
    start_drawing,
)
from ovtraj.runs import Run, RunStore

logger = logging.getLogger(__name__)


class BatchExecutor(Protocol):
    """Runs the batches of a run: started on ``__enter__``, stopped on ``__exit__``.

    The driver holds it open for the DoE and every infill run (a pool's processes keep
    their mission context between runs) and stops it before the plan.
    """

    def __enter__(self) -> BatchExecutor: ...

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> bool | None: ...

    def evaluate(self, run: Run) -> Run:
        """Evaluate the run's pending batches (each stored where the run is); return the
        run finished (its manifest ``complete``), or raise naming the batches that failed."""
        ...

    def side_pool(self) -> Executor | None:
        """Processes that score the surrogate candidates and draw the plots while this
        process runs NSGA-II; ``None``: both here."""
        ...


@dataclass(frozen=True)
class PipelineRequest:
    """What the caller asks for beyond the scenario: the DoE's size and seed (``None``:
    ``mission.doe``'s), a stored DoE run to start from, the scenario file that run must
    match, refitting, and the pick of the verified front."""

    samples: int | None = None
    seed: int | None = None
    from_run: str | None = None
    config: str | Path | None = None
    refit: bool = False
    pick: Pick = field(default_factory=Pick)


@dataclass
class PipelineOutcome:
    """The DoE run, the scenario it holds, the verified front and the plan of the pick."""

    doe_run: Run
    scenario: Scenario
    result: PipelineResult
    planned: dict[str, Any]

    @property
    def converged(self) -> bool:
        return bool(self.result.summary["converged"])

    @property
    def verdict(self) -> str:
        """Whether the verification loop converged, and why it stopped (one paragraph)."""
        return stop_explanation(self.result.summary, self.scenario.mission.verify)


def drive_pipeline(
    scenario: Scenario,
    launch_fit: LaunchFit,
    store: RunStore,
    code: str,
    executor: BatchExecutor,
    request: PipelineRequest | None = None,
    *,
    progress: Callable[[str], None] | None = None,
) -> PipelineOutcome:
    """DoE -> surrogates -> NSGA-II -> verification and infill -> pick -> plan (the module
    notes). Raises :class:`PipelineError` (bad input, no front), the executor's errors for
    batches, :class:`~ovtraj.pipeline.steps.OptimiserStopped` and
    :class:`~ovtraj.mission.plan_check.PlanMismatch` (a plan that does not fly its front point)."""
    if scenario.mission is None:
        raise PipelineError("the scenario has no mission section")
    request = request or PipelineRequest()
    say = progress or logger.info
    with executor:
        doe_run, scenario = pipeline_doe_run(
            scenario,
            store,
            code,
            samples=request.samples,
            seed=request.seed,
            from_run=request.from_run,
            config=request.config if request.from_run else None,
        )
        say(f"DoE run {doe_run.id}: {len(doe_run.samples())} samples")
        executor.evaluate(doe_run)
        side = executor.side_pool()
        # Without the executor's processes, a large DoE's fits get a pool of their own.
        fitting = (
            nullcontext(side)
            if side is not None
            else fitting_pool(scenario, len(doe_run.samples()))
        )
        with fitting as side:
            steps = PipelineSteps(
                evaluate=executor.evaluate,
                fit=partial(fit_step, refit=request.refit, executor=side),
                front=partial(front_step, refit=request.refit),
                draw=partial(draw_views, executor=side),
                predraw=None if side is None else partial(start_drawing, executor=side),
            )
            result = run_pipeline(
                scenario, doe_run, store=store, code=code, steps=steps, progress=say
            )
    planned = write_mission_plan(scenario, launch_fit, store, result, request.pick)
    return PipelineOutcome(doe_run, scenario, result, planned)
