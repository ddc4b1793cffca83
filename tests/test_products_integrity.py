"""Stored products and printed results: one records module, checked stores.

- every former private copy of ``plain`` (``_plain``, ``_finite``, ``_json_default``,
  ``_json_safe``) is gone and its user gives null for NaN (``ovtraj.store.records.plain``);
- the product primitives (:mod:`ovtraj.store.products`): marker written last, checked reads,
  an interrupted write completed, a stored file never overwritten;
- the deorbit-burn Monte Carlo store: declared schema, digests in the batch markers,
  a rewritten value or a missing part refused naming the file.

The surrogate set, the surrogate front, the pipeline result and the launch fit are
tested in ``test_surrogate.py``, ``test_pipeline.py`` and ``test_launch_fit.py``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from ovtraj.store.files import StoreError
from ovtraj.store.products import Product, directory_lock
from ovtraj.studies.deorbit_burn.montecarlo import RUN_SCHEMA, STORED_RUN_SCHEMA
from ovtraj.studies.deorbit_burn.store import MonteCarloRun

NAN = np.float64(math.nan)

FORMER_COPIES = {
    "ovtraj.launch.result": "_plain",
    "ovtraj.studies.maneuver.result": "_plain",
    "ovtraj.studies.optimal_entry.result": "_plain",
    "ovtraj.studies.deorbit_burn.result": "_plain",
    "ovtraj.studies.deorbit_burn.report": "_plain",
    "flows.deorbit_monte_carlo": "_plain",
    "ovtraj.mission.fly": "_finite",
    "ovtraj.studies.deorbit_burn.store": "_json_default",
    "ovtraj.cli": "_json_safe",
}


@pytest.mark.parametrize(("module", "name"), sorted(FORMER_COPIES.items()))
def test_the_private_copies_of_plain_are_gone(module, name):
    assert not hasattr(importlib.import_module(module), name)


def _all_nan(cls, **given):
    """An instance of a result dataclass with NaN (numpy's) in every field not given."""
    values = {
        f.name: NAN
        for f in dataclasses.fields(cls)
        if f.name not in given
        and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING
    }
    return cls(**values, **given)


def test_result_rows_give_null_for_nan():
    from ovtraj.mission.flight_report import FlightReport
    from ovtraj.studies.deorbit_burn.result import DeorbitBurnResult
    from ovtraj.studies.maneuver.result import ManeuverResult
    from ovtraj.studies.optimal_entry.result import OptimalEntryResult

    row = _all_nan(DeorbitBurnResult).to_row()
    assert row and all(value is None for value in row.values())
    doc = _all_nan(ManeuverResult, burns=[]).to_json()
    assert all(value is None for key, value in doc.items() if key != "burns")
    row = _all_nan(OptimalEntryResult).to_row()
    assert row and all(value is None for value in row.values())
    report = FlightReport(
        ok=False,
        reason=None,
        landed_within_stated_miss=False,
        stated_miss_m=NAN,
        miss_distance_m=math.inf,
        terminal={"speed_mps": NAN, "trace": np.array([1.0, math.nan])},
    ).to_dict()
    assert report["stated_miss_m"] is None and report["miss_distance_m"] is None
    assert report["terminal"] == {"speed_mps": None, "trace": [1.0, None]}
    for value in (row, doc, report):
        json.dumps(value, allow_nan=False)


def test_deorbit_burn_report_gives_null_for_nan(monkeypatch):
    from ovtraj.studies.deorbit_burn import report as report_module
    from ovtraj.studies.deorbit_burn.result import DeorbitBurnResult

    @dataclasses.dataclass
    class Record:
        values: dict

        def as_dict(self):
            return self.values

    result = _all_nan(
        DeorbitBurnResult, history=(Record({"iteration": 1, "dv_mps": NAN, "u": math.nan}),)
    )

    class Solver:
        def __init__(self, problem):
            pass

        def solve(self, strategy=None):
            return result

    monkeypatch.setattr(report_module, "BurnSolver", Solver)
    monkeypatch.setattr(report_module, "published_comparison", lambda *a, **k: [])
    report = report_module.deorbit_burn_report(object())
    assert report["history"] == [{"iteration": 1, "dv_mps": None, "u": None}]
    assert report["result"]["dv_mps"] is None
    json.dumps(report, allow_nan=False)


def test_monte_carlo_statistics_give_null_for_nan():
    """The flow's and the CLI's statistics rows: one run per strategy has no spread."""
    from ovtraj.store.records import plain
    from ovtraj.studies.deorbit_burn.montecarlo import monte_carlo_summary

    frame = _frame(runs=[0], strategies=[1])
    rows = [plain(row) for row in monte_carlo_summary(frame).to_dict(orient="records")]
    assert rows[0]["entry_fpa_error_deg_std"] is None
    assert rows[0]["dv_mps_mean"] == pytest.approx(frame["dv_mps"].iloc[0])
    json.dumps(rows, allow_nan=False)


# -- the product primitives ---------------------------------------------------------------


def test_product_marker_is_written_last_and_lists_every_file(tmp_path):
    product = Product(tmp_path / "p", "marker.json")
    schema = RUN_SCHEMA
    table = pa.Table.from_pandas(_frame(), schema=schema, preserve_index=False)
    with product.writing() as out:
        assert not out.complete
        out.write_bytes("blob.bin", b"payload")
        out.write_table("table.parquet", table, schema)
        assert not product.exists()  # nothing is readable before the marker
        content = out.finish({"kind": "test"})
    marker = json.loads(product.marker_path.read_text())
    assert marker == content and marker["kind"] == "test"
    for name in ("blob.bin", "table.parquet"):
        payload = (product.directory / name).read_bytes()
        assert marker["files"][name] == {
            "bytes": len(payload),
            "sha256": hashlib.sha256(payload).hexdigest(),
        }
    assert product.read_bytes("blob.bin", product.marker()) == b"payload"
    with pytest.raises(StoreError, match=r"marker\.json: lists no other\.bin"):
        product.read_bytes("other.bin", product.marker())
    (product.directory / "blob.bin").write_bytes(b"payloaD")
    with pytest.raises(StoreError, match=r"blob\.bin: changed since it was stored"):
        product.read_bytes("blob.bin", product.marker())
    # Complete: the same content again is a no-op, other content is refused.
    with product.writing() as out:
        assert out.complete
        with pytest.raises(StoreError, match=r"table\.parquet: already stored"):
            out.write_table("table.parquet", table.slice(1), schema)


def test_one_writer_at_a_time(tmp_path):
    """The product's lock is a flock on its directory: a second writer waits, then gives
    up naming the directory; nothing is left behind once released."""
    product = Product(tmp_path / "p", "marker.json")
    with directory_lock(product.directory):
        with pytest.raises(StoreError, match=r"p: another process is still writing it"):
            with product.writing(wait_s=0.2):
                pass
    with product.writing(wait_s=0.2) as out:
        out.finish({})
    assert sorted(p.name for p in product.directory.iterdir()) == ["marker.json"]


def test_a_marker_without_digests_is_refused_naming_it(tmp_path):
    (tmp_path / "meta.json").write_text('{"kind": "old"}')
    with pytest.raises(StoreError, match=r"meta\.json: lists no file digests"):
        Product(tmp_path, "meta.json").marker()


# -- the deorbit-burn Monte Carlo store -----------------------------------------------------


def _row(run: int, strategy: int) -> dict:
    """A made-up row of RUN_SCHEMA (no simulation); run 2 failed (NaN errors)."""
    row = {}
    for field in RUN_SCHEMA:
        if pa.types.is_floating(field.type):
            row[field.name] = (run + strategy) / 10
        elif pa.types.is_integer(field.type):
            row[field.name] = 3
        elif pa.types.is_boolean(field.type):
            row[field.name] = True
        else:
            row[field.name] = None
    row.update(run=run, strategy=strategy)
    if run == 2:
        row.update(ok=False, reason="made up", entry_u_error_deg=math.nan)
        row.update(along_track_error_km=math.nan)
    return row


def _frame(runs=(0, 1, 2), strategies=(1, 2)) -> pd.DataFrame:
    rows = [_row(run, strategy) for run in runs for strategy in strategies]
    return pa.Table.from_pylist(rows, schema=RUN_SCHEMA).to_pandas()


@pytest.fixture
def mc_run(tmp_path):
    run = MonteCarloRun.create(
        tmp_path, resolved={"name": "test"}, runs=6, strategies=[1, 2], seed=1, code="test"
    )
    assert run.write_batch(0, _frame(runs=(0, 1, 2)))
    assert run.write_batch(3, _frame(runs=(3, 4)))
    return run


def test_monte_carlo_store_markers_list_digests_and_results_are_checked(mc_run):
    run = mc_run
    assert run.done_runs() == {0, 1, 2, 3, 4}
    assert not run.write_batch(0, _frame(runs=(0,)))  # stored: nothing written
    marker = json.loads((run.directory / "batches" / "00000.json").read_text())
    part = run.directory / "runs" / "part-00000.parquet"
    payload = part.read_bytes()
    assert marker["files"] == {
        "runs/part-00000.parquet": {
            "bytes": len(payload),
            "sha256": hashlib.sha256(payload).hexdigest(),
        }
    }
    # The timing is in the marker, not in the results.
    assert [row[:2] for row in marker["timing"]["wall_time_s"]] == [
        [r, s] for r in (0, 1, 2) for s in (1, 2)
    ]
    assert len(run.timing()) == 10 and "wall_time_s" not in run.results()
    # The declared schema whatever the data: "reason" all null in batch 3, NaN as null.
    for path in (part, run.directory / "runs" / "part-00003.parquet"):
        assert pq.read_schema(path).equals(STORED_RUN_SCHEMA)
    stored = pq.read_table(part)
    assert stored.column("entry_u_error_deg").null_count == 2
    frame = run.results()
    assert len(frame) == 10 and frame["entry_u_error_deg"].isna().sum() == 2
    assert run.config == {"name": "test"}
    # One value rewritten in a still valid Parquet file.
    dv = stored.column("dv_mps").to_pylist()
    dv[0] += 1.0
    index = stored.schema.get_field_index("dv_mps")
    pq.write_table(stored.set_column(index, "dv_mps", pa.array(dv)), part)
    with pytest.raises(StoreError, match=r"part-00000\.parquet: changed since it was stored"):
        run.results()
    part.write_bytes(payload)
    run.results()
    part.unlink()
    with pytest.raises(StoreError, match=r"part-00000\.parquet: missing"):
        run.results()
    (run.directory / "config.json").write_text('{"name": "other"}\n')
    with pytest.raises(StoreError, match=r"config\.json: changed since it was stored"):
        _ = run.config


def test_monte_carlo_part_without_marker_is_replaced_and_old_markers_refused(tmp_path):
    run = MonteCarloRun.create(
        tmp_path, resolved={"name": "test"}, runs=2, strategies=[1], seed=1, code="test"
    )
    part = run.directory / "runs" / "part-00000.parquet"
    part.parent.mkdir(parents=True)
    part.write_bytes(b"half a file")  # an interrupted write
    assert run.write_batch(0, _frame(runs=(0, 1), strategies=(1,)))
    assert len(run.results()) == 2
    (run.directory / "batches" / "00002.json").write_text('{"batch": 2, "runs": [2]}')
    with pytest.raises(StoreError, match=r"00002\.json: not a batch marker"):
        run.done_runs()
    info = json.loads((run.directory / "run.json").read_text())
    del info["format"]
    (run.directory / "run.json").write_text(json.dumps(info))
    with pytest.raises(StoreError, match=r"run\.json: store format 1"):
        MonteCarloRun.create(
            tmp_path, resolved={"name": "test"}, runs=2, strategies=[1], seed=1, code="test"
        )


def test_monte_carlo_summary_json_is_plain(mc_run):
    path = mc_run.write_summary({"statistics": [{"std": NAN, "n": np.int64(3)}]})
    assert json.loads(Path(path).read_text()) == {"statistics": [{"std": None, "n": 3}]}
