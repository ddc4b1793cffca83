"""Dispersed Monte Carlo of a mission plan, closed loop and open loop: the runs flown.

A run draws its errors (:mod:`.montecarlo_draw`: the carrier's release, the solid stages,
the on-board estimates, each impulse's execution, the atmosphere and the aerodynamics) and
flies them twice, open loop (the plan as stored, no correction) and closed loop (the
corrections a real mission makes, each by the stage's own method from the on-board
estimate: :mod:`.montecarlo_flight`, :mod:`.montecarlo_guidance`). Each loop ends with a
:class:`~.montecarlo_outcome.RunOutcome`: the landing point and miss, the path maxima,
the dV each manoeuvre spent, or the stage that failed and why; the statistics of many
(:mod:`.montecarlo_statistics`) compare them with the plan's stated miss, limits and dV.

This module flies a list of runs: :func:`monte_carlo` (the outcomes, in memory) and
:func:`simulate_batch` (the rows a stored batch holds,
:mod:`ovtraj.mission.montecarlo_store`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

import pandas as pd

from ovtraj.config import scenario_from_dict
from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.config.force_model import ForceModelSettings
from ovtraj.environment import require_pinned_kernel
from ovtraj.mission.montecarlo_draw import draw_run
from ovtraj.mission.montecarlo_flight import fly_closed_loop, fly_open_loop
from ovtraj.mission.montecarlo_outcome import RUN_SCHEMA, RunOutcome, outcome_row
from ovtraj.mission.plan import MissionPlan

logger = logging.getLogger(__name__)

__all__ = ["monte_carlo", "simulate_batch"]


def monte_carlo(
    plan: MissionPlan,
    config: DispersionsConfig,
    runs: int,
    seed: int,
    *,
    progress: Any = None,
    force_model: ForceModelSettings | None = None,
) -> list[tuple[RunOutcome, RunOutcome]]:
    """``runs`` draws, each flown closed and open loop (serially, in this process);
    ``progress(done, total)`` after each run (and a debug log line). With ``force_model``
    the closed loop flies under the high-fidelity sky; the open loop is the J2 replay."""
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    pairs = []
    for run in range(runs):
        draw = draw_run(config, seed, run, len(plan.impulses()))
        pairs.append(
            (
                fly_closed_loop(plan, draw, config, scenario, force_model),
                fly_open_loop(plan, draw),
            )
        )
        logger.debug(
            "run %d/%d: closed loop %s, open loop %s",
            run + 1,
            runs,
            *("landed" if o.landed else f"failed ({o.failed_stage})" for o in pairs[-1]),
        )
        if progress is not None:
            progress(run + 1, runs)
    return pairs


def simulate_batch(
    plan: MissionPlan,
    config: DispersionsConfig,
    runs: list[int],
    seed: int,
    force_model: ForceModelSettings | None = None,
    on_run: Callable[[], None] | None = None,
) -> pd.DataFrame:
    """Rows of ``RUN_SCHEMA``: each run flown closed and open loop (timed per row); the
    closed loop under ``force_model``'s sky when given (:func:`monte_carlo`);
    ``on_run()`` after each run (a progress bar's step)."""
    require_pinned_kernel()  # stored rows: the pinned OpenBLAS kernel only (ovtraj.environment)
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    rows = []
    for run in runs:
        draw = draw_run(config, seed, run, len(plan.impulses()))
        for fly in (
            lambda d=draw: fly_closed_loop(plan, d, config, scenario, force_model),
            lambda d=draw: fly_open_loop(plan, d),
        ):
            start = time.perf_counter()
            outcome = fly()
            rows.append(outcome_row(outcome, time.perf_counter() - start))
        if on_run is not None:
            on_run()
    return pd.DataFrame(rows, columns=RUN_SCHEMA.names)
