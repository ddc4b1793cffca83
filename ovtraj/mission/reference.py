"""The mission chain's reference values: stored once, compared after every change.

A fixed set of designs (a seeded Latin hypercube over the design bounds,
``configs/mission_reference.yaml``) is evaluated with the shipped scenario; the totals,
each stage's impulse and the landing miss are stored in
``data/reference/mission_chain/`` (``values.parquet`` of :data:`REFERENCE_SCHEMA`, and
``meta.json``, written last, with its digest, the code version and the settings).
:func:`compare` evaluates the same designs again and lists every difference beyond the
configured tolerances: speed work on the chain must leave its results where they were.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
from pydantic import Field

from ovtraj.config import Scenario
from ovtraj.config.base import StrictModel, bounded, load_model
from ovtraj.mission.chain import DESIGN_NAMES, MissionContext, MissionDesign, evaluate
from ovtraj.paths import config_path, reference_dir
from ovtraj.store.products import Product
from ovtraj.store.records import table_from_rows
from ovtraj.target_sources import load_scenario

SETTINGS_FILE = "mission_reference.yaml"
MARKER = "meta.json"
VALUES = "values.parquet"

REFERENCE_SCHEMA = pa.schema(
    [
        pa.field("design", pa.int64()),
        *(pa.field(name, pa.float64()) for name in DESIGN_NAMES),
        pa.field("feasible", pa.bool_()),
        pa.field("failed_stage", pa.string()),
        pa.field("t_total_s", pa.float64()),
        pa.field("dv_total_mps", pa.float64()),
        pa.field("m_load_kg", pa.float64()),
        pa.field("rendezvous_dv_mps", pa.float64()),
        pa.field("transfer_dv_mps", pa.float64()),
        pa.field("deorbit_dv_mps", pa.float64()),
        pa.field("landing_miss_m", pa.float64()),
    ]
)


class ReferenceTolerances(StrictModel):
    dv_mps: float = bounded(unit="m/s", gt=0)
    time_s: float = bounded(unit="s", gt=0)
    landing_miss_m: float = bounded(unit="m", gt=0)
    payload_kg: float = bounded(unit="kg", gt=0)


class PlaneAimBounds(StrictModel):
    """What the rendezvous of a reference design must reach with the plane aimed at it:
    its dV over its coplanar two-body Hohmann cost, and the angle between the
    chaser's and the target's planes at its first burn."""

    hohmann_ratio_max: float = bounded(ge=1, le=10)
    plane_difference_max_deg: float = bounded(unit="deg", gt=0, le=1)


class ReferenceSettings(StrictModel):
    scenario: str = Field(description="a shipped scenario file of configs/")
    designs: int = bounded(ge=1, le=10000)
    seed: int = bounded(ge=0, le=2**32 - 1)
    tolerances: ReferenceTolerances
    # Optional: the markers stored by older versions hold settings without it.
    plane_aim: PlaneAimBounds | None = None
    # Optional: the markers stored before them hold settings without them.
    extra_designs: list[tuple[float, float, float]] = Field(
        default_factory=list,
        max_length=100,
        description="designs (H_P0 km, H_dp km, t_dsp h) added after the hypercube's: where "
        "a rule of the chain acts that the hypercube does not reach",
    )


def load_settings(path: str | Path | None = None) -> ReferenceSettings:
    return load_model(ReferenceSettings, path or config_path(SETTINGS_FILE))


def reference_directory() -> Path:
    return reference_dir() / "mission_chain"


def designs(scenario: Scenario, settings: ReferenceSettings) -> list[MissionDesign]:
    """The reference designs: ``settings.designs`` of a seeded hypercube over the bounds,
    then ``settings.extra_designs``."""
    from ovtraj.mission.design_space import latin_hypercube

    table = latin_hypercube(scenario.mission.design_bounds, settings.designs, settings.seed)
    return [
        MissionDesign(**{name: float(getattr(row, name)) for name in DESIGN_NAMES})
        for row in table.itertuples(index=False)
    ] + [MissionDesign(*map(float, design)) for design in settings.extra_designs]


def context(settings: ReferenceSettings) -> MissionContext:
    """The shipped scenario's context with its stored launch fit."""
    from ovtraj.launch.launch_fit import find_launch_fit

    scenario = load_scenario(config_path(settings.scenario))
    fit = find_launch_fit(scenario)
    if fit is None:
        raise ValueError(f"{settings.scenario}: no stored launch fit for the scenario")
    return MissionContext(scenario, fit)


def _stage(record: Any, stage: str, key: str, scale: float = 1.0) -> float | None:
    value = record.stages.get(stage, {}).get(key)
    return None if value is None else float(value) * scale


def values(context: MissionContext, chosen: list[MissionDesign]) -> pd.DataFrame:
    """One row of :data:`REFERENCE_SCHEMA` per design, evaluated now."""
    rows = []
    for k, design in enumerate(chosen):
        record = evaluate(context, design)
        totals = record.totals()
        rows.append(
            {
                "design": k,
                **design.as_dict(),
                "feasible": bool(totals["feasible"]),
                "failed_stage": totals["failed_stage"],
                "t_total_s": totals["t_total_s"],
                "dv_total_mps": totals["dv_total_mps"],
                "m_load_kg": totals["m_load_kg"],
                "rendezvous_dv_mps": _stage(record, "rendezvous", "dv_total_mps"),
                "transfer_dv_mps": _stage(record, "transfer", "dv_total_mps"),
                "deorbit_dv_mps": _stage(record, "deorbit", "dv_mps"),
                "landing_miss_m": _stage(record, "reentry", "miss_distance_km", 1e3),
            }
        )
    return table_from_rows(rows, REFERENCE_SCHEMA, "mission reference").to_pandas()


def store(directory: Path, frame: pd.DataFrame, document: dict[str, Any]) -> Path:
    """Write the values and, last, the marker (never over a stored reference)."""
    product = Product(directory, MARKER)
    if product.exists():
        raise FileExistsError(f"{directory}: a reference is stored; remove it deliberately first")
    with product.writing() as writer:
        table = pa.Table.from_pandas(frame, schema=REFERENCE_SCHEMA, preserve_index=False)
        writer.write_table(VALUES, table, REFERENCE_SCHEMA)
        writer.finish(document)
    return directory / MARKER


def load(directory: Path | None = None) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The stored values (every file checked against the marker's digest) and the marker."""
    product = Product(directory or reference_directory(), MARKER)
    marker = product.marker()
    return product.read_frame(VALUES, REFERENCE_SCHEMA, marker), marker


# Compared columns and the tolerance (ReferenceTolerances field) of each.
COMPARED = {
    "t_total_s": "time_s",
    "dv_total_mps": "dv_mps",
    "m_load_kg": "payload_kg",
    "rendezvous_dv_mps": "dv_mps",
    "transfer_dv_mps": "dv_mps",
    "deorbit_dv_mps": "dv_mps",
    "landing_miss_m": "landing_miss_m",
}


def differences(
    stored: pd.DataFrame, now: pd.DataFrame, tolerances: ReferenceTolerances
) -> list[str]:
    """Every difference beyond tolerance, one line each (empty: the results held)."""
    found = []
    for old, new in zip(stored.to_dict("records"), now.to_dict("records"), strict=True):
        k = old["design"]
        if any(old[name] != new[name] for name in DESIGN_NAMES):
            found.append(f"design {k}: not the stored design (the hypercube moved)")
            continue
        for name in ("feasible", "failed_stage"):
            if old[name] != new[name] and not (_missing(old[name]) and _missing(new[name])):
                found.append(f"design {k}: {name} {old[name]!r} now {new[name]!r}")
        for column, tolerance_name in COMPARED.items():
            a, b = old[column], new[column]
            if _missing(a) and _missing(b):
                continue
            tolerance = getattr(tolerances, tolerance_name)
            if _missing(a) or _missing(b) or abs(a - b) > tolerance:
                found.append(f"design {k}: {column} {a!r} now {b!r} (tolerance {tolerance:g})")
    return found


def _missing(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))
