"""The catalog's SQL predicate (``ovtraj runs --where``): one expression, never a second
statement; DuckDB's memory and thread limits and the process's address space bound it;
every failure one line naming ``--where``. The table is a real catalog frame of
:data:`ovtraj.tracking.catalog_schema.SCHEMA` queried by DuckDB itself."""

from __future__ import annotations

import resource

import pandas as pd
import pytest

from ovtraj.tracking.catalog_query import query
from ovtraj.tracking.catalog_schema import SCHEMA, catalog_settings


@pytest.fixture
def frame() -> pd.DataFrame:
    rows = pd.DataFrame({name: pd.Series([None] * 3, dtype=object) for name in SCHEMA.names})
    rows["kind"] = ["run", "plan", "run"]
    rows["id"] = ["a" * 16, "b" * 16, "c" * 16]
    rows["source"] = ["a", "b", "c"]
    rows["source_sha256"] = "0" * 64
    rows["tags"] = "{}"
    rows["dv_total_mps"] = [None, 201.5, None]
    return rows


def test_a_predicate_selects_rows_in_the_catalog_order(frame):
    assert query(frame, "kind = 'run'")["id"].tolist() == ["a" * 16, "c" * 16]
    assert query(frame, "dv_total_mps > 200")["kind"].tolist() == ["plan"]
    assert query(frame, "id IN (SELECT id FROM catalog WHERE kind = 'plan')")["id"].tolist() == [
        "b" * 16
    ]


@pytest.mark.parametrize(
    "where",
    [
        "false); SELECT 999 AS _row --",  # a stacked statement
        "true) UNION SELECT 999 --",  # a second query in the same statement
        "kind = 'run'; DROP TABLE catalog",
        "(SET threads = 64) IS NULL",
    ],
)
def test_a_second_statement_is_a_syntax_error_and_nothing_runs(frame, where):
    with pytest.raises(ValueError, match=r"^--where: Parser Error") as err:
        query(frame, where)
    assert "\n" not in str(err.value)


def test_a_value_beyond_the_memory_limit_is_one_line_and_the_process_stays_small(frame):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    bound = resource.getrlimit(resource.RLIMIT_AS)
    limit = catalog_settings().query_memory_mib
    with pytest.raises(ValueError, match=rf"more than {limit} MiB \(catalog.query_memory_mib\)"):
        query(frame, "length(repeat('x', 1000000000)) > 0")  # 1 GB of one string
    grown = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - before
    assert grown < limit * 2**20
    assert resource.getrlimit(resource.RLIMIT_AS) == bound  # restored
    assert query(frame, "length(repeat('x', 1000)) > 0")["id"].tolist() == frame["id"].tolist()


@pytest.mark.parametrize(
    ("where", "expected"),
    [
        ("kind = 1", "--where: Conversion Error"),
        ("no_such_column = 1", "--where: Binder Error"),
        ("1/", "--where: Parser Error"),
    ],
)
def test_every_duckdb_error_is_one_line_naming_where(frame, where, expected):
    with pytest.raises(ValueError, match=f"^{expected}") as err:
        query(frame, where)
    assert "\n" not in str(err.value)
