"""A run's evaluated samples as surrogate training data."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ovtraj.config import Scenario, scenario_from_dict
from ovtraj.mission import DESIGN_NAMES
from ovtraj.optimize import MISSION_OBJECTIVES
from ovtraj.runs import Run, RunStore, prepare_run
from ovtraj.runs.ids import results_config
from ovtraj.runs.store import StoreError
from ovtraj.target_sources import load_scenario


@dataclass(frozen=True)
class TrainingData:
    sample_ids: np.ndarray
    designs: np.ndarray  # (n, 3) in DESIGN_NAMES order, physical units
    outputs: dict[str, np.ndarray]  # objective -> (n,), NaN where infeasible
    feasible: np.ndarray
    # Parts of the totals from the stage rows (NaN where the stage did not get there):
    # the rendezvous wait and the three impulses of dV_total.
    components: dict[str, np.ndarray] = field(default_factory=dict)

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
    ids = merged["sample_id"]
    return TrainingData(
        sample_ids=ids.to_numpy(dtype=np.int64),
        designs=merged[list(DESIGN_NAMES)].to_numpy(dtype=float),
        outputs=outputs,
        feasible=feasible,
        components={
            name: _stage_column(run, stage, column, ids)
            for name, (stage, column) in COMPONENTS.items()
        },
    )


# Training-data name -> (stage, column of the stage's rows).
COMPONENTS = {
    "rendezvous_wait_s": ("rendezvous", "wait_time_s"),
    # The wait the rendezvous checks against its limit; kept when it refuses one too.
    "rendezvous_phasing_wait_s": ("rendezvous", "phasing_wait_s"),
    "dv_rendezvous_mps": ("rendezvous", "dv_total_mps"),
    "dv_transfer_mps": ("transfer", "dv_total_mps"),
    "dv_deorbit_mps": ("deorbit", "dv_mps"),
    # 0 when the deorbit's correction pinned the burn at the preparation orbit's start.
    "deorbit_wait_s": ("deorbit", "wait_time_s"),
    # 0 when the ground track crosses no entry region within the deorbit's horizon.
    "deorbit_passes": ("deorbit", "passes_in_region"),
}


def _stage_column(run: Run, stage: str, column: str, ids: pd.Series) -> np.ndarray:
    rows = run.stage(stage)
    if len(rows) == 0 or column not in rows:
        return np.full(len(ids), np.nan)
    values = rows.set_index("sample_id")[column].reindex(ids.to_numpy())
    return pd.to_numeric(values, errors="coerce").to_numpy(dtype=float, na_value=np.nan)


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


def pipeline_doe_run(
    scenario: Scenario,
    store: RunStore,
    code: str,
    *,
    samples: int | None = None,
    seed: int | None = None,
    from_run: str | None = None,
    config: str | Path | None = None,
) -> tuple[Run, Scenario]:
    """The DoE run the pipeline starts from, and the scenario to use with it.

    ``from_run``: that stored run, with its own scenario (``config`` may change only
    the post-processing settings, :func:`run_scenario`); otherwise the scenario's Latin
    hypercube run (``samples`` and ``seed`` default to ``mission.doe``), created or reopened.
    """
    if from_run:
        run = store.run(from_run)
        return run, run_scenario(run, config)
    settings = scenario.mission.doe
    run = prepare_run(
        scenario,
        samples=settings.samples if samples is None else samples,
        seed=settings.seed if seed is None else seed,
        code=code,
        store=store,
    )
    return run, scenario
