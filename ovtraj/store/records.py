"""Results as records: plain values, JSON text and Arrow tables of a declared schema.

The one place where typed results become stored or printed data:

- :func:`plain` turns numpy scalars and arrays into Python values and every
  non-finite float into ``None``, recursively (a stored or printed result never
  holds NaN: JSON has no NaN and Parquet has null);
- :func:`json_text` is ``json.dumps`` of the plain value, refusing what JSON cannot hold
  (:func:`ovtraj.store.files.json_data` reads one back, bounded);
- :func:`json_default` is the one numpy -> Python conversion, as ``json.dumps``'s
  ``default`` hook for callers that keep NaN as it is (:func:`plain` uses it too);
- :func:`record_schema` declares a dataset's columns (all nullable unless named
  ``required``), and :func:`table_from_rows` / :func:`table_from_frame` build a
  table of exactly that schema, refusing a column the schema does not declare and a
  declared column the data lacks (unless the caller names it ``optional``). So every
  part of a dataset has the same columns and types, whatever the mix of feasible and
  infeasible rows in it;
- :class:`Column` and :class:`RowColumns` declare a result's row once: each column's
  name, Arrow type, unit and meaning, and how it is read from the result, from which
  both the row (:meth:`RowColumns.row`) and the schema (:attr:`RowColumns.schema`) are
  built. The unit and meaning are the reader's: the stored schema holds no metadata.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import PurePath
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

__all__ = [
    "BOOL",
    "FLOAT",
    "INT",
    "TEXT",
    "Column",
    "RowColumns",
    "SchemaError",
    "json_default",
    "json_text",
    "plain",
    "record_schema",
    "table_from_frame",
    "table_from_rows",
]

FLOAT = pa.float64()
INT = pa.int64()
BOOL = pa.bool_()
TEXT = pa.string()


class SchemaError(ValueError):
    """Data that does not fit its dataset's declared schema (a programming error)."""


def json_default(value: Any) -> Any:
    """A numpy scalar as the Python one (``item()``), a numpy array as nested lists
    (``tolist()``); ``TypeError`` for anything else: ``json.dumps``'s ``default`` hook."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"a {type(value).__name__} is not JSON data")


def plain(value: Any) -> Any:
    """``value`` with numpy types as Python ones and non-finite floats as ``None``.

    Mappings become dicts, tuples and arrays lists (a 0-d array its element), paths
    strings; other values are returned as they are.
    """
    if isinstance(value, np.generic | np.ndarray):
        value = json_default(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, (str, bool, int)) or value is None:
        return value
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, PurePath):
        return str(value)
    return value


def json_text(value: Any, *, indent: int | None = 2, sort_keys: bool = False) -> str:
    """JSON of :func:`plain` ``(value)``; ``TypeError`` for what JSON cannot hold."""
    return json.dumps(plain(value), indent=indent, sort_keys=sort_keys, allow_nan=False)


def record_schema(
    columns: Iterable[tuple[str, pa.DataType]],
    *,
    required: Sequence[str] = (),
) -> pa.Schema:
    """A dataset's declared columns, in order; nullable except those in ``required``."""
    fields = [pa.field(name, kind, nullable=name not in required) for name, kind in columns]
    names = [f.name for f in fields]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise SchemaError(f"columns declared twice: {', '.join(repeated)}")
    unknown = sorted(set(required) - set(names))
    if unknown:
        raise SchemaError(f"required columns not declared: {', '.join(unknown)}")
    return pa.schema(fields)


def _check_columns(
    found: Iterable[str], schema: pa.Schema, dataset: str, optional: Collection[str] = ()
) -> None:
    """SchemaError naming the columns ``found`` has that ``schema`` does not declare, then
    the declared ones it lacks (but those named ``optional``)."""
    found = set(found)
    extra = sorted(found - set(schema.names))
    if extra:
        raise SchemaError(f"{dataset}: columns not in the declared schema: {', '.join(extra)}")
    missing = [name for name in schema.names if name not in found and name not in optional]
    if missing:
        raise SchemaError(f"{dataset}: declared columns missing: {', '.join(missing)}")


def table_from_rows(
    rows: Sequence[Mapping[str, Any]],
    schema: pa.Schema,
    dataset: str,
    *,
    optional: Collection[str] = (),
) -> pa.Table:
    """Rows (dicts) as a table of ``schema``: a key it does not declare is an error, and
    so is a declared column a row lacks, unless it is one of ``optional`` (columns the
    data may not have, null in the rows without them)."""
    unknown = sorted(set(optional) - set(schema.names))
    if unknown:
        raise SchemaError(f"{dataset}: optional columns not declared: {', '.join(unknown)}")
    for row in rows:
        _check_columns(row.keys(), schema, dataset, optional)
    try:
        return pa.Table.from_pylist([plain(dict(row)) for row in rows], schema=schema)
    except (pa.ArrowException, TypeError, ValueError) as err:
        raise SchemaError(f"{dataset}: rows do not fit the declared schema ({err})") from None


def table_from_frame(frame: pd.DataFrame, schema: pa.Schema, dataset: str) -> pa.Table:
    """A data frame as a table of ``schema`` (every declared column present, no other)."""
    _check_columns(frame.columns, schema, dataset)
    try:
        table = pa.Table.from_pandas(frame[list(schema.names)], schema=schema, preserve_index=False)
    except (pa.ArrowException, TypeError, ValueError) as err:
        raise SchemaError(f"{dataset}: data does not fit the declared schema ({err})") from None
    return table.replace_schema_metadata(None)


@dataclass(frozen=True)
class Column:
    """One column of a result's row: its ``name`` (units in the name's suffix: ``_s``,
    ``_m``, ``_km``, ``_mps``, ``_deg``, ``_utc``...), its Arrow ``kind``, ``doc`` (the
    unit and what it holds, for the reader) and ``get``, its value read from the result
    (None where the result has none; NaN becomes None in the row)."""

    name: str
    kind: pa.DataType
    doc: str
    get: Callable[[Any], Any]


class RowColumns:
    """A result's row declared once, as :class:`Column` s in their stored order: the row
    of a result (:meth:`row`) and the dataset's :attr:`schema` are both built from it."""

    def __init__(self, columns: Iterable[Column], *, required: Sequence[str] = ()) -> None:
        self.columns = tuple(columns)
        self.schema = record_schema([(c.name, c.kind) for c in self.columns], required=required)

    def row(self, result: Any) -> dict[str, Any]:
        """Every declared column of ``result``, in order, as :func:`plain` values."""
        return {c.name: plain(c.get(result)) for c in self.columns}
