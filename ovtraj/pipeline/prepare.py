"""One preparation of the whole pipeline for ``ovtraj pipeline`` and the mission flow:
the scenario with its target, the runner, the run store, the launch fit and the
driver's request, from the command's options or the flow's parameters (the same names).

Both adapters call :func:`prepare_pipeline` and hand what it returns to
:func:`ovtraj.pipeline.drive.drive_pipeline`; they differ only in how a missing launch
fit is solved (:mod:`ovtraj.runs.preparation`: in the command's process, or as the
launch-fit subflow) and in how a refusal is said (one line and exit 2, or a failed flow
run with that line as its message).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ovtraj.config import Scenario
from ovtraj.launch.launch_fit import LaunchFit
from ovtraj.pipeline.drive import PipelineRequest
from ovtraj.pipeline.pick import Pick
from ovtraj.runs import RunStore
from ovtraj.runs.preparation import (
    LaunchFitter,
    mission_scenario,
    required_launch_fit,
    runner_choice,
)
from ovtraj.runs.runners import RunnerChoice


@dataclass(frozen=True)
class PipelineInputs:
    """What the driver is given: the scenario (its target replaced when asked), its launch
    fit, the run store, where the batches run and the request."""

    scenario: Scenario
    launch_fit: LaunchFit
    store: RunStore
    choice: RunnerChoice
    request: PipelineRequest


def prepare_pipeline(
    config: str | Path | None,
    *,
    pick: Pick,
    fit_missing: LaunchFitter,
    samples: int | None = None,
    seed: int | None = None,
    from_run: str | None = None,
    refit: bool = False,
    store: str | None = None,
    target: str | None = None,
    runner: str | None = None,
    workers: int | None = None,
    dask_address: str | None = None,
    as_options: bool = False,
) -> PipelineInputs:
    """The pipeline's inputs: the scenario file ``config`` (default: the shipped one) with
    its target replaced by ``target`` (a TLE/OMM file or URL), its runner (``runner``,
    ``workers``, ``dask_address``, else ``mission.doe``'s), its run store (``store``, else
    ``mission.doe.store``, else the workspace's), its launch fit (solved by
    ``fit_missing`` first or refused, as configs/orchestration.yaml
    ``preparation.launch_fit`` says), and the request of ``samples``, ``seed``,
    ``from_run``, ``refit`` and the checked ``pick``.

    The cheap checks come before the launch fit (minutes when it is solved): a bad
    scenario, a scenario without a mission section or a bad runner raises ``ValueError``
    (a :class:`~ovtraj.config.ConfigError` for the scenario) naming the field, as the
    command's options with ``as_options``; a refused launch fit raises
    :class:`~ovtraj.runs.preparation.LaunchFitMissing`."""
    scenario = mission_scenario(config, target)
    choice = runner_choice(
        scenario.mission.doe, runner, dask_address, workers, as_options=as_options
    )
    run_store = RunStore.for_scenario(scenario, config, store)
    fit = required_launch_fit(scenario, fit_missing, target=target)
    request = PipelineRequest(
        samples=samples,
        seed=seed,
        from_run=from_run,
        config=None if config is None else Path(config),
        refit=refit,
        pick=pick,
    )
    return PipelineInputs(scenario, fit, run_store, choice, request)
