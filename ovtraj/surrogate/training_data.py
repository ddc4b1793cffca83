"""The training data of a surrogate fit: checked, and hashed.

:func:`checked_training_data` refuses unusable data with one line naming the argument
and the samples at fault (shapes, names, NaN or infinite values where a value is
needed, no feasible sample); :func:`training_data_hash` names the exact data a set was
fitted on (stored with it, compared by the caches).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence

import numpy as np

from ovtraj.surrogate.scaling import SurrogateError
from ovtraj.surrogate.tables import FEASIBLE

__all__ = ["checked_left_out", "checked_training_data", "output_columns", "training_data_hash"]


def training_data_hash(
    X: np.ndarray,
    outputs: dict[str, np.ndarray],
    feasible: np.ndarray,
) -> str:
    """SHA-256 (first 16 hex digits) of the exact training data.

    Hashed in this order, each as little-endian float64 bytes preceded by a tag and its
    shape: X, feasible (0/1), then every output in sorted name order. NaNs are hashed as
    one canonical NaN, so only the values count, not a NaN's payload bits.
    """
    digest = hashlib.sha256()

    def add(tag: str, values: np.ndarray) -> None:
        array = np.ascontiguousarray(np.asarray(values, dtype=float), dtype="<f8")
        array = np.where(np.isnan(array), np.nan, array).astype("<f8")
        digest.update(f"{tag}{array.shape}".encode() + b"\0")
        digest.update(array.tobytes())

    add("X", X)
    add("feasible", np.asarray(feasible, dtype=bool).astype(float))
    for name in sorted(outputs):
        add(f"output:{name}", outputs[name])
    return digest.hexdigest()[:16]


def checked_training_data(
    X: np.ndarray,
    outputs: dict[str, np.ndarray],
    feasible: np.ndarray,
    input_names: tuple[str, ...],
    sample_ids: np.ndarray | None,
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """``fit_surrogates``' data as float arrays: inputs (n, d), outputs, flags, sample ids
    (default 0..n-1); SurrogateError naming the first fault."""
    x = _checked_inputs(X, input_names)
    n = x.shape[0]
    ids = _checked_ids(sample_ids, n)
    flags = np.asarray(feasible)
    if flags.shape != (n,) or flags.dtype != bool:
        raise SurrogateError(
            f"feasible: expected a boolean array of shape ({n},) (one flag per row of X), "
            f"got dtype {flags.dtype} and shape {flags.shape}"
        )
    bad_rows = np.flatnonzero(~np.all(np.isfinite(x), axis=1))
    if bad_rows.size:
        raise SurrogateError(
            f"X: NaN or infinite inputs at sample_id {_ids(bad_rows, ids)}; every input must "
            "be finite"
        )
    values = _checked_outputs(outputs, n)
    n_feasible = int(np.count_nonzero(flags))
    if n_feasible == 0:
        raise SurrogateError(
            f"all {n} samples are infeasible; the surrogates need feasible samples"
        )
    for name, y in values.items():
        bad = np.flatnonzero(flags & ~np.isfinite(y))
        if bad.size:
            raise SurrogateError(
                f"output {name!r}: NaN or infinite values at feasible samples (sample_id "
                f"{_ids(bad, ids)}); a feasible sample needs a finite value of every output"
            )
    return x, values, flags, ids


def _ids(indices: np.ndarray, sample_ids: np.ndarray, limit: int = 8) -> str:
    shown = ", ".join(str(int(sample_ids[i])) for i in indices[:limit])
    more = f", ... ({indices.size} in all)" if indices.size > limit else ""
    return f"[{shown}{more}]"


def _checked_inputs(X: np.ndarray, input_names: tuple[str, ...]) -> np.ndarray:
    """The inputs (n, d) as floats, at least one sample and one input, a name for each."""
    try:
        x = np.array(X, dtype=float)
    except (TypeError, ValueError) as err:
        raise SurrogateError(f"X: not a numeric array ({err})") from None
    if x.ndim != 2:
        raise SurrogateError(f"X: expected a 2-D array (n samples, d inputs), got shape {x.shape}")
    n, dim = x.shape
    if n == 0:
        raise SurrogateError("no samples: X has 0 rows; the surrogates need feasible samples")
    if dim == 0:
        raise SurrogateError("X has 0 columns; at least one input is needed")
    if len(input_names) != dim or len(set(input_names)) != dim:
        raise SurrogateError(
            f"input_names: {len(input_names)} names {tuple(input_names)} for X with {dim} "
            "columns; one distinct name per column is needed"
        )
    return x


def _checked_ids(sample_ids: np.ndarray | None, n: int) -> np.ndarray:
    """``n`` distinct int64 sample ids (default 0..n-1)."""
    ids = np.arange(n) if sample_ids is None else np.asarray(sample_ids)
    if ids.shape != (n,) or not np.issubdtype(ids.dtype, np.integer):
        raise SurrogateError(
            f"sample_ids: expected {n} integers (shape ({n},)), got dtype {ids.dtype} and "
            f"shape {ids.shape}"
        )
    if np.unique(ids).size != n:
        raise SurrogateError("sample_ids: the ids must be distinct")
    return ids.astype(np.int64)


def _checked_outputs(outputs: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """Every output as floats (n,), each named other than the classifier."""
    values: dict[str, np.ndarray] = {}
    for name, column in outputs.items():
        if not isinstance(name, str) or not name or name == FEASIBLE:
            raise SurrogateError(
                f"outputs: invalid name {name!r} (a non-empty string other than {FEASIBLE!r})"
            )
        try:
            y = np.array(column, dtype=float)
        except (TypeError, ValueError) as err:
            raise SurrogateError(f"output {name!r}: not numeric ({err})") from None
        if y.shape != (n,):
            raise SurrogateError(
                f"output {name!r}: expected shape ({n},) (one value per row of X), got {y.shape}"
            )
        values[name] = y
    return values


def output_columns(
    output_inputs: Mapping[str, Sequence[str]],
    input_names: tuple[str, ...],
    outputs: dict[str, np.ndarray],
) -> dict[str, tuple[int, ...]]:
    """Output name -> the column indices (in input order) of its own inputs."""
    columns: dict[str, tuple[int, ...]] = {}
    for output, names in output_inputs.items():
        if output not in outputs:
            raise SurrogateError(
                f"output_inputs: {output!r} is not an output (outputs: {tuple(outputs)})"
            )
        listed = [names] if isinstance(names, str) else list(names)
        unknown = [name for name in listed if name not in input_names]
        if not listed or unknown:
            raise SurrogateError(
                f"output_inputs[{output!r}]: {listed} must be one or more of the inputs "
                f"{input_names}"
            )
        columns[output] = tuple(k for k, name in enumerate(input_names) if name in listed)
    return columns


def checked_left_out(
    left_out: Mapping[str, np.ndarray], values: dict[str, np.ndarray], n: int
) -> dict[str, np.ndarray]:
    """``fit_surrogates``' ``left_out``, checked: known outputs, one flag per sample."""
    checked = {}
    for name, mask in left_out.items():
        if name not in values:
            raise SurrogateError(f"left_out: {name!r} is not an output (outputs: {tuple(values)})")
        flags = np.asarray(mask)
        if flags.shape != (n,) or flags.dtype != bool:
            raise SurrogateError(
                f"left_out[{name!r}]: expected a boolean array of shape ({n},), got dtype "
                f"{flags.dtype} and shape {flags.shape}"
            )
        checked[name] = flags
    return checked
