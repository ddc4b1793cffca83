"""Each result's row is declared once (``ovtraj.store.records.RowColumns``): its row and
its schema come from the same columns, and a table refuses a row that lacks a declared
column or has one more, naming it."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest

from ovtraj.astro.epoch import Epoch
from ovtraj.deorbit.result import ROW_SCHEMA as DEORBIT_ROW_SCHEMA
from ovtraj.deorbit.result import DeorbitResult
from ovtraj.launch.ascent_optimization import PhaseRecord
from ovtraj.launch.insertion import MATCH_PHASE
from ovtraj.launch.result import PHASES, LaunchResult
from ovtraj.launch.result import ROW_SCHEMA as LAUNCH_ROW_SCHEMA
from ovtraj.mission.chain import TOTALS_SCHEMA, MissionDesign, MissionRecord
from ovtraj.reentry.result import ROW_SCHEMA as REENTRY_ROW_SCHEMA
from ovtraj.reentry.result import ReentryResult
from ovtraj.rendezvous.result import ROW_SCHEMA as RENDEZVOUS_ROW_SCHEMA
from ovtraj.rendezvous.result import RendezvousResult
from ovtraj.store.records import (
    FLOAT,
    INT,
    Column,
    RowColumns,
    SchemaError,
    record_schema,
    table_from_rows,
)

EPOCH = Epoch.from_iso("2026-12-01T00:00:00Z")


def _phase(name: str) -> PhaseRecord:
    return PhaseRecord(name, 412.5, 0.0, 0.4, True, True, 12, 130, 1.5, "done")


RESULTS = {
    "launch": (LaunchResult(False, "x", 250e3, "ascending", EPOCH), LAUNCH_ROW_SCHEMA),
    "rendezvous": (RendezvousResult("rendezvous", False, "x", EPOCH, 0.0), RENDEZVOUS_ROW_SCHEMA),
    "deorbit": (DeorbitResult(False, "x", EPOCH), DEORBIT_ROW_SCHEMA),
    "reentry": (ReentryResult(False, "x", EPOCH), REENTRY_ROW_SCHEMA),
    "totals": (MissionRecord(MissionDesign(300.0, 200.0, 1.5)), TOTALS_SCHEMA),
}


@pytest.mark.parametrize("stage", RESULTS)
def test_a_row_has_exactly_the_declared_columns_in_order(stage):
    result, schema = RESULTS[stage]
    row = result.totals() if stage == "totals" else result.to_row()
    assert list(row) == schema.names
    table = table_from_rows([row], schema, stage)
    assert table.schema == schema


def test_a_launch_row_names_every_phase_the_solve_ran_or_not():
    result = LaunchResult(
        True, None, 250e3, "ascending", EPOCH, phases=[_phase("slsqp"), _phase(MATCH_PHASE)]
    )
    row = result.to_row()
    # The grid's phases, run or not, in the declared order; a solve to an insertion
    # point's phase after them (a cached solve's row, not a grid table's).
    assert list(row)[: len(LAUNCH_ROW_SCHEMA)] == LAUNCH_ROW_SCHEMA.names
    assert row["slsqp_payload_kg"] == 412.5 and row["slsqp_accepted"] is True
    assert all(row[f"{p.replace('-', '_')}_payload_kg"] is None for p in PHASES if p != "slsqp")
    assert row[f"{MATCH_PHASE}_iterations"] == 12
    assert set(row) - set(LAUNCH_ROW_SCHEMA.names) == {
        f"{MATCH_PHASE}_{suffix}"
        for suffix in (
            "payload_kg",
            "violation",
            "residual",
            "accepted",
            "iterations",
            "trajectories",
            "time_s",
        )
    }


def test_a_missing_or_an_extra_column_is_refused_naming_it():
    schema = record_schema([("a", INT), ("b", FLOAT)])
    with pytest.raises(SchemaError, match=r"demo: declared columns missing: b$"):
        table_from_rows([{"a": 1, "b": 2.0}, {"a": 2}], schema, "demo")
    with pytest.raises(SchemaError, match=r"demo: columns not in the declared schema: c$"):
        table_from_rows([{"a": 1, "b": 2.0, "c": 3}], schema, "demo")
    table = table_from_rows([{"a": 1}, {"a": 2, "b": 0.5}], schema, "demo", optional=("b",))
    assert table.column("b").to_pylist() == [None, 0.5]
    with pytest.raises(SchemaError, match="optional columns not declared: z"):
        table_from_rows([{"a": 1, "b": 2.0}], schema, "demo", optional=("z",))


def test_a_declaration_gives_the_row_and_the_schema():
    declared = RowColumns(
        [
            Column("n", INT, "a count", lambda r: r["n"]),
            Column("x_m", FLOAT, "m: a length, NaN stored as null", lambda r: r["x"]),
        ],
        required=("n",),
    )
    assert declared.schema == pa.schema(
        [pa.field("n", INT, nullable=False), pa.field("x_m", FLOAT, nullable=True)]
    )
    assert declared.row({"n": np.int64(3), "x": float("nan")}) == {"n": 3, "x_m": None}
