"""The two model steps of the pipeline, stored in the run and reused by content.

Layout inside a run's directory::

    surrogates/<fit_id>/    the fitted set (ovtraj.surrogate): models, meta.json,
                            validation.parquet, predictions.parquet, parity-*.png
    fronts/<front_id>/      front.parquet (designs, predicted objectives, p_feasible),
                            meta.json (hypervolume, NSGA-II figures), front.png

``fit_id`` hashes the training data (:func:`ovtraj.surrogate.training_data_hash`),
the design bounds, the surrogate settings and the code version; ``front_id`` the
fit id, the optimisation settings and the code version. A stored result is loaded
instead of recomputed; with ``refit`` it is recomputed, compared with the stored one
and never overwritten.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.config import Scenario
from ovtraj.files import atomic_bytes, atomic_parquet, read_json, read_parquet
from ovtraj.mission import DESIGN_NAMES
from ovtraj.optimize import Normalisation, SurrogateFront, surrogate_front
from ovtraj.pipeline.data import TrainingData
from ovtraj.pipeline.features import (
    MissionSurrogates,
    fit_mission_surrogates,
    load_surrogates,
)
from ovtraj.runs import Run
from ovtraj.runs.doe import bounds_arrays
from ovtraj.surrogate import SurrogateSet, fit_surrogates, training_data_hash


def content_id(content: dict[str, Any]) -> str:
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


@dataclass
class FitOutcome:
    surrogates: SurrogateSet | MissionSurrogates
    directory: Path
    fit_id: str
    reused: bool  # loaded from the store


@dataclass
class FrontOutcome:
    front: SurrogateFront
    directory: Path
    front_id: str
    reused: bool
    matches_stored: bool | None = None  # refit: the recomputed front equals the stored one


def fit_step(
    run: Run, data: TrainingData, scenario: Scenario, code: str, *, refit: bool = False
) -> FitOutcome:
    """Surrogates of the run's samples: loaded when stored, else fitted and stored."""
    settings = scenario.mission.surrogate
    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    data_hash = training_data_hash(data.designs, {**data.outputs, **data.components}, data.feasible)
    fit_id = content_id(
        {
            "data": data_hash,
            "bounds": [lower.tolist(), upper.tolist()],
            "settings": settings.model_dump(mode="json"),
            "code": code,
        }
    )
    directory = run.directory / "surrogates" / fit_id
    stored = (directory / "meta.json").is_file()
    if stored and not refit:
        return FitOutcome(load_surrogates(directory), directory, fit_id, reused=True)
    if settings.phase_input:
        surrogates = fit_mission_surrogates(data, scenario, lower, upper)
        parts = surrogates.parts
    else:
        surrogates = fit_surrogates(
            data.designs,
            data.outputs,
            data.feasible,
            lower,
            upper,
            settings,
            input_names=DESIGN_NAMES,
            sample_ids=data.sample_ids,
        )
        parts = (surrogates,)
    if not stored:
        from ovtraj.plots.surrogate import parity_plots

        for part in parts:
            parity_plots(part, directory)
        surrogates.save(directory, meta={"run_id": run.id, "fit_id": fit_id, "code": code})
    return FitOutcome(surrogates, directory, fit_id, reused=False)


def front_step(
    run: Run, fit: FitOutcome, scenario: Scenario, code: str, *, refit: bool = False
) -> FrontOutcome:
    """NSGA-II on the surrogates: loaded when stored, else optimised and stored."""
    settings = scenario.mission.optimize
    normalisation = Normalisation.mission(settings)
    front_id = content_id(
        {"fit": fit.fit_id, "settings": settings.model_dump(mode="json"), "code": code}
    )
    directory = run.directory / "fronts" / front_id
    stored = (directory / "meta.json").is_file()
    if stored and not refit:
        return FrontOutcome(load_front(directory, normalisation), directory, front_id, True)
    initial = _real_front_designs(run, normalisation) if settings.seed_with_real_front else None
    front = surrogate_front(fit.surrogates, normalisation, settings, initial=initial)
    if stored:
        previous = read_parquet(directory / "front.parquet")
        same = previous.equals(front.to_frame())
        return FrontOutcome(front, directory, front_id, False, matches_stored=same)
    meta = {
        "front_id": front_id,
        "fit_id": fit.fit_id,
        "run_id": run.id,
        "code": code,
        "points": len(front),
        "hypervolume": front.hypervolume,
        "nsga2": front.info,
        "settings": settings.model_dump(mode="json"),
    }
    atomic_parquet(directory / "front.parquet", front.to_frame())
    from ovtraj.plots.front import front_plot

    front_plot(
        directory / "front.png",
        normalisation,
        surrogate=front.predicted,
        samples=_feasible_totals(run),
        title=f"surrogate front {front_id} (run {run.id})",
    )
    atomic_bytes(directory / "meta.json", json.dumps(meta, indent=2).encode())
    return FrontOutcome(front, directory, front_id, reused=False)


def load_front(directory: Path, normalisation: Normalisation) -> SurrogateFront:
    frame = read_parquet(directory / "front.parquet")
    meta = read_json(directory / "meta.json")
    predicted = frame[list(normalisation.names)].reset_index(drop=True)
    return SurrogateFront(
        designs=frame[list(DESIGN_NAMES)].reset_index(drop=True),
        predicted=predicted,
        normalised=normalisation.normalise(predicted.to_numpy(dtype=float)),
        p_feasible=frame["p_feasible"].to_numpy(dtype=float),
        hypervolume=float(meta["hypervolume"]),
        info=dict(meta.get("nsga2") or {}),
    )


def _real_front_designs(run: Run, normalisation: Normalisation) -> np.ndarray:
    """Designs of the run's non-dominated feasible samples (real values)."""
    from ovtraj.optimize import non_dominated

    feasible = _feasible_totals(run)
    if len(feasible) == 0:
        return np.zeros((0, len(DESIGN_NAMES)))
    values = normalisation.normalise(feasible[list(normalisation.names)].to_numpy(dtype=float))
    designs = run.samples().set_index("sample_id").loc[feasible["sample_id"], list(DESIGN_NAMES)]
    return designs.to_numpy(dtype=float)[non_dominated(values)]


def _feasible_totals(run: Run) -> pd.DataFrame:
    totals = run.totals()
    return totals[totals["feasible"].astype(bool)] if len(totals) else totals


def unit_designs(scenario: Scenario, designs: np.ndarray) -> np.ndarray:
    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    return (np.asarray(designs, dtype=float) - lower) / (upper - lower)
