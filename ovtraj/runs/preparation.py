"""What a DoE run or a pipeline needs before its first batch, the same for the command
line and the flows: the scenario with its target, its mission section, the runner and
the launch fit.

A scenario whose launch fit is not stored yet (a new element set moves the target's
plane, so its fit has another key) is fitted first or refused, as
``preparation.launch_fit`` of configs/orchestration.yaml says: ``fit`` or ``require``.
How a missing fit is solved is the caller's: the command line solves the grid in its
own process (:func:`solve_launch_fit`, as ``ovtraj launch-fit``), a flow runs the
launch-fit flow as a subflow (each point a cached task). Both store the fit under its
key where :func:`~ovtraj.launch.launch_fit.find_launch_fit` looks, so either gives the
run the same fit.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from ovtraj.config import Scenario
from ovtraj.config.mission import DoeSettings
from ovtraj.config.orchestration import load_orchestration
from ovtraj.launch import launch_input
from ovtraj.launch.launch_fit import (
    LaunchFit,
    Progress,
    find_launch_fit,
    fit_roots,
    launch_fit,
    launch_fit_key,
)
from ovtraj.paths import scenario_file
from ovtraj.runs.runners import RunnerChoice, choose_runner
from ovtraj.target_sources import load_scenario_with_target

logger = logging.getLogger(__name__)

LaunchFitter = Callable[[Scenario], object]
"""Solves the scenario's launch fit and stores it under its key (what it returns is not
used: the fit is read back from the store)."""


class LaunchFitMissing(ValueError):
    """No launch fit is stored for the scenario and none may be (or was) solved here."""


def mission_scenario(config: str | Path | None, target: str | None = None) -> Scenario:
    """The scenario file ``config`` (default: the shipped one), its target replaced by the
    TLE/OMM file or URL ``target`` when given; refused without a mission section."""
    path = scenario_file(config)
    scenario = load_scenario_with_target(path, target)
    if scenario.mission is None:
        raise ValueError(f"{path}: the scenario has no mission section")
    return scenario


def runner_choice(
    settings: DoeSettings,
    runner: str | None,
    dask_address: str | None,
    workers: int | None = None,
    *,
    as_options: bool = False,
) -> RunnerChoice:
    """The runner chosen (:func:`ovtraj.runs.runners.choose_runner`: the option or
    parameter, else ``mission.doe``'s), its pool of ``workers`` when given. A bad choice
    raises ``ValueError`` naming it, as the command's options with ``as_options``.

    ``workers`` sizes the pool only: a run's batches are cut by the config's
    ``mission.doe.workers`` (:meth:`ovtraj.config.mission.DoeSettings.batch_size_for`), so
    the stored run is the same for any number of workers."""
    choice = choose_runner(settings, runner, dask_address, as_options=as_options)
    if workers is None:
        return choice
    if workers < 1:
        name = "--workers" if as_options else "workers ="
        raise ValueError(f"{name} {workers}: must be at least 1")
    return replace(choice, workers=workers)


def required_launch_fit(
    scenario: Scenario, fit_missing: LaunchFitter, *, target: str | None = None
) -> LaunchFit:
    """The scenario's stored launch fit; when there is none, ``fit_missing`` solves it
    first (``preparation.launch_fit: fit``) or :class:`LaunchFitMissing` says which
    command fits it (``require``; ``target``: the command's ``--target``, named there)."""
    fit = find_launch_fit(scenario)
    if fit is not None:
        return fit
    if load_orchestration().preparation.launch_fit == "require":
        also = f" --target {target}" if target else ""
        raise LaunchFitMissing(
            "no launch fit for this scenario (its target and launch settings): run "
            f"`ovtraj launch-fit CONFIG{also}` (~4 min) or the launch-fit flow first "
            "(configs/orchestration.yaml preparation.launch_fit: require)"
        )
    logger.info("no launch fit for this scenario yet: solving it first (~4 min)")
    fit_missing(scenario)
    fit = find_launch_fit(scenario)
    if fit is None:
        raise LaunchFitMissing(
            f"{scenario.name}: the launch fit solved for this scenario is not in "
            f"{fit_roots()[0]} (key {launch_fit_key(scenario)})"
        )
    return fit


def solve_launch_fit(
    scenario: Scenario, directory: str | Path | None = None, on_progress: Progress | None = None
) -> tuple[LaunchFit, Path]:
    """Solve the scenario's launch grid in this process, fit it and save it in
    ``directory`` (default: the workspace's ``launch_fit/<key>``, where
    :func:`~ovtraj.launch.launch_fit.find_launch_fit` looks). ``on_progress`` as
    :func:`~ovtraj.launch.launch_fit.solve_grid`'s. Returns the fit and its folder."""
    key = launch_fit_key(scenario)
    fit = launch_fit(launch_input(scenario), scenario.launch.fit, key=key, on_progress=on_progress)
    folder = Path(directory or fit_roots()[0] / key).resolve()
    fit.save(folder)
    return fit, folder
