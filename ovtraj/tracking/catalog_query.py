"""The catalog queried with SQL: DuckDB's relational ``filter`` over the table's columns
(:data:`~ovtraj.tracking.catalog_schema.SCHEMA`), bounded in time, memory and reach
(``catalog`` of configs/orchestration.yaml; ``ovtraj runs --where``)."""

from __future__ import annotations

import contextlib
import resource
import threading
from collections.abc import Iterator

import pandas as pd
import pyarrow as pa

from ovtraj.formatting import printable
from ovtraj.tracking.catalog_schema import SCHEMA, catalog_settings

__all__ = ["query"]


def query(frame: pd.DataFrame, where: str | None) -> pd.DataFrame:
    """The catalog rows for which the SQL predicate ``where`` holds (DuckDB's dialect over
    the columns of :data:`SCHEMA`, e.g. ``kind = 'plan' AND dv_total_mps > 220``), in the
    catalog's order.

    ``where`` is parsed as one expression (DuckDB's relational ``filter``), never pasted
    into a statement: a ``;`` or an unbalanced ``)`` is a syntax error, so no second
    statement runs. The query sees only this table: DuckDB's access to files and the
    network is off and its settings locked; it runs on ``catalog.query_threads`` threads
    within ``catalog.query_memory_mib`` (DuckDB's limit, and the process's address space
    while it runs, :func:`_address_space_limit`), and is interrupted past
    ``catalog.query_time_limit_s``. Every failure is a :class:`ValueError` of one line
    naming ``--where``."""
    if where is None or not where.strip():
        return frame
    settings = catalog_settings()
    if len(where) > settings.where_max_chars:
        raise ValueError(
            f"--where: {len(where)} characters, at most {settings.where_max_chars} "
            "(catalog.where_max_chars)"
        )
    import duckdb

    table = pa.Table.from_pandas(frame, schema=SCHEMA, preserve_index=False)
    table = table.append_column("_row", pa.array(range(len(frame)), pa.int64()))
    connection = duckdb.connect(":memory:")
    try:
        connection.register("catalog", table)
        connection.execute(f"SET memory_limit = '{settings.query_memory_mib}MiB'")
        connection.execute(f"SET threads = {settings.query_threads}")
        connection.execute("SET enable_external_access = false")
        connection.execute("SET lock_configuration = true")
        timer = threading.Timer(settings.query_time_limit_s, connection.interrupt)
        timer.start()
        try:
            with _address_space_limit(settings.query_memory_mib * 2**20):
                relation = connection.table("catalog").filter(where)
                found = relation.project("_row").order("_row").fetchnumpy()["_row"]
        except duckdb.InterruptException:
            raise ValueError(
                f"--where: the query ran longer than {settings.query_time_limit_s:g} s "
                "(catalog.query_time_limit_s)"
            ) from None
        except (duckdb.OutOfMemoryException, MemoryError):
            raise ValueError(
                f"--where: the query needs more than {settings.query_memory_mib} MiB "
                "(catalog.query_memory_mib)"
            ) from None
        except duckdb.Error as err:
            text = printable(str(err).splitlines()[0] if str(err) else type(err).__name__)
            raise ValueError(f"--where: {text[:300]}") from None
        finally:
            timer.cancel()
    finally:
        connection.close()
    rows = [int(k) for k in found]
    if any(not 0 <= k < len(frame) for k in rows):  # the filter keeps the table's own rows
        raise ValueError("--where: the query returned rows the catalog does not hold")
    return frame.iloc[rows].reset_index(drop=True)


@contextlib.contextmanager
def _address_space_limit(extra_bytes: int) -> Iterator[None]:
    """The process's address space bounded to its current size plus ``extra_bytes`` while
    the block runs (Linux; elsewhere only DuckDB's own limit holds). DuckDB's memory_limit
    counts its buffers, not the strings a scalar function builds: ``repeat('x', 1e9)``
    grew the process by 2.1 GB under a 512 MiB memory_limit. Under this bound the
    allocation fails and DuckDB reports an out-of-memory error instead."""
    size = _address_space_bytes()
    if size is None:
        yield
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    wanted = size + extra_bytes
    if soft != resource.RLIM_INFINITY and soft <= wanted:
        yield  # already bounded tighter by whoever started us
        return
    if hard != resource.RLIM_INFINITY:
        wanted = min(wanted, hard)
    resource.setrlimit(resource.RLIMIT_AS, (wanted, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def _address_space_bytes() -> int | None:
    """The process's virtual size [B] (``VmSize`` of /proc/self/status), None off Linux."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None
