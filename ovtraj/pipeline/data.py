"""A run's evaluated samples as surrogate training data."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ovtraj.config import Scenario, load_scenario, scenario_from_dict
from ovtraj.mission import DESIGN_NAMES
from ovtraj.optimize import MISSION_OBJECTIVES
from ovtraj.runs import Run
from ovtraj.runs.store import StoreError, results_config


@dataclass(frozen=True)
class TrainingData:
    sample_ids: np.ndarray
    designs: np.ndarray  # (n, 3) in DESIGN_NAMES order, physical units
    outputs: dict[str, np.ndarray]  # objective -> (n,), NaN where infeasible
    feasible: np.ndarray

    def __len__(self) -> int:
        return len(self.sample_ids)

    def frame(self) -> pd.DataFrame:
        frame = pd.DataFrame(self.designs, columns=list(DESIGN_NAMES))
        frame.insert(0, "sample_id", self.sample_ids)
        for name, values in self.outputs.items():
            frame[name] = values
        frame["feasible"] = self.feasible
        return frame


def training_data(run: Run) -> TrainingData:
    """Every evaluated sample of the run (samples joined with the stored totals)."""
    totals = run.totals()
    if len(totals) == 0:
        raise StoreError(f"run {run.id} has no evaluated samples (run the DoE first)")
    merged = run.samples().merge(
        totals[["sample_id", "feasible", *(o.name for o in MISSION_OBJECTIVES)]],
        on="sample_id",
        how="inner",
    )
    feasible = merged["feasible"].to_numpy(dtype=bool)
    outputs = {}
    for objective in MISSION_OBJECTIVES:
        values = merged[objective.name].to_numpy(dtype=float, na_value=np.nan)
        outputs[objective.name] = np.where(feasible, values, np.nan)
    return TrainingData(
        sample_ids=merged["sample_id"].to_numpy(dtype=np.int64),
        designs=merged[list(DESIGN_NAMES)].to_numpy(dtype=float),
        outputs=outputs,
        feasible=feasible,
    )


def run_scenario(run: Run, config: str | Path | None = None) -> Scenario:
    """The run's own scenario; a ``config`` file may change only what is done with the
    results (``mission.doe/surrogate/optimize/verify/plan``), not the chain's settings."""
    own = scenario_from_dict(run.config, str(run.directory / "config.json"))
    if config is None:
        return own
    scenario = load_scenario(config)
    if results_config(scenario.resolved()) != results_config(own.resolved()):
        raise ValueError(
            f"{config}: differs from run {run.id}'s scenario in settings that change the "
            "chain's results; only mission.doe/surrogate/optimize/verify/plan may differ"
        )
    return scenario
