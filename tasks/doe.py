"""Prefect task: one batch of mission evaluations, cached on its inputs and the code."""

from __future__ import annotations

from typing import Any

from prefect import task
from prefect.cache_policies import INPUTS

from ovtraj.config import scenario_from_dict
from ovtraj.launch.fit import find_launch_fit
from ovtraj.mission import MissionContext, MissionRecord
from ovtraj.runs import execute


@task(name="mission-batch", cache_policy=INPUTS, persist_result=True)
def mission_batch_task(
    resolved_scenario: dict[str, Any],
    batch: list[dict[str, float]],
    code: str,
) -> list[MissionRecord]:
    """Evaluate the mission chain for each sample row (sample_id and design variables).

    The cache key is the hash of the resolved scenario, the batch's samples and the
    code version, so a re-run with nothing changed reads the persisted records.
    """
    import pandas as pd

    scenario = scenario_from_dict(resolved_scenario)
    fit = find_launch_fit(scenario)
    if fit is None:
        raise RuntimeError("no launch fit for this scenario: run flows/launch_fit.py first")
    return execute.evaluate_batch(MissionContext(scenario, fit), pd.DataFrame(batch))
