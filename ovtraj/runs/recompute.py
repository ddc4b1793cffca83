"""A stored run's samples evaluated again on this machine and compared with the stored rows
(``ovtraj verify RUN --recompute N``).

On a machine where ovtraj pins OpenBLAS's kernel (:mod:`ovtraj.environment`), the same
inputs store the same bytes, so a recomputed row equals the stored one exactly. Elsewhere
(another CPU family, another BLAS, other library versions) the last bits move; the
declared tolerances of ``configs/reproducibility.yaml`` bound how far they may. This
compares every column of the stage rows and the totals of ``N`` samples spread evenly
over the run's sample ids:

- numbers: the largest absolute difference against the column's tolerance (by its name's
  unit, or by its name); a value stored but not recomputed (or the reverse) is beyond any;
  counts of solver steps are reported, not bounded;
- ``feasible`` and ``failed_stage``: exactly, as is which stages each sample reached;
- other text (reasons, solver messages, epochs written from the times) is not compared:
  its wording or rounding follows the numbers above.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from ovtraj.config import scenario_from_dict
from ovtraj.config.reproducibility import FILE, RecomputeSettings, load_reproducibility
from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import MissionContext
from ovtraj.runs.batch_tables import result_rows
from ovtraj.runs.execute import evaluate_batch
from ovtraj.runs.schemas import DATASETS
from ovtraj.runs.store import Run
from ovtraj.store.records import table_from_rows
from ovtraj.version import code_version

__all__ = ["ColumnCheck", "RecomputeError", "RecomputeReport", "recompute", "spread_ids"]

# Columns compared exactly (the verdict of a sample); every other text column is not compared.
EXACT_TEXT = ("failed_stage",)
COMPARED_DATASETS = ("totals", *(name for name in DATASETS if name.startswith("stages/")))


class RecomputeError(ValueError):
    """The run cannot be recomputed here (no launch fit, a bad count, an undeclared
    tolerance): one line naming what is missing."""


@dataclass(frozen=True)
class ColumnCheck:
    """One compared column: the largest difference found (a count of differing values for
    an exact column; inf when a value is stored but not recomputed, or the reverse), its
    tolerance (None: reported only; 0 for an exact column) and the verdict."""

    dataset: str
    column: str
    unit: str
    largest: float
    tolerance: float | None
    exact: bool = False

    @property
    def verdict(self) -> str:
        if self.tolerance is None:
            return "reported"
        return "ok" if self.largest <= self.tolerance else "beyond"

    def to_json(self) -> dict[str, Any]:
        return {
            "dataset": self.dataset,
            "column": self.column,
            "unit": self.unit,
            "largest_difference": self.largest if math.isfinite(self.largest) else None,
            "missing_values": not math.isfinite(self.largest),
            "tolerance": self.tolerance,
            "exact": self.exact,
            "verdict": self.verdict,
        }


@dataclass
class RecomputeReport:
    """What :func:`recompute` found."""

    run_id: str
    sample_ids: list[int]
    stored_code: str | None  # the code version that stored the run
    code: str  # the code version that recomputed it (another one may differ for its own sake)
    checks: list[ColumnCheck] = field(default_factory=list)

    @property
    def beyond(self) -> list[ColumnCheck]:
        return [check for check in self.checks if check.verdict == "beyond"]

    @property
    def ok(self) -> bool:
        return not self.beyond

    def to_json(self) -> dict[str, Any]:
        return {
            "samples": self.sample_ids,
            "stored_code_version": self.stored_code,
            "code_version": self.code,
            "ok": self.ok,
            "beyond": [f"{c.dataset}.{c.column}" for c in self.beyond],
            "columns": [check.to_json() for check in self.checks],
            "tolerances": f"configs/{FILE}",
        }


def spread_ids(sample_ids: list[int], count: int) -> list[int]:
    """``count`` of ``sample_ids`` spread evenly over them in id order, first and last
    included (all of them when there are no more): the same choice every time."""
    ordered = sorted(sample_ids)
    if count >= len(ordered):
        return ordered
    if count == 1:
        return [ordered[0]]
    picks = np.round(np.linspace(0, len(ordered) - 1, count)).astype(int)
    return [ordered[i] for i in picks]


def recompute(run: Run, count: int, settings: RecomputeSettings | None = None) -> RecomputeReport:
    """Evaluate ``count`` of the run's stored samples again here and compare (module notes).

    Raises :class:`RecomputeError` for a count beyond ``recompute.max_samples``, a run with
    no stored sample, a column without a declared tolerance or no launch fit for the run's
    scenario; :class:`~ovtraj.environment.BlasKernelError` when this process runs another
    OpenBLAS kernel than the pin (:func:`~ovtraj.runs.execute.evaluate_batch`)."""
    settings = settings or load_reproducibility().recompute
    if not 1 <= count <= settings.max_samples:
        raise RecomputeError(
            f"--recompute {count}: must be from 1 to {settings.max_samples} "
            f"(recompute.max_samples of configs/{FILE})"
        )
    totals = run.totals()
    if len(totals) == 0:
        raise RecomputeError(f"run {run.id} has no stored sample: nothing to recompute")
    chosen = spread_ids([int(i) for i in totals["sample_id"]], count)
    tolerances = {c: _tolerance(settings, c) for name in COMPARED_DATASETS for c in _columns(name)}
    scenario = scenario_from_dict(run.config, f"{run.directory / 'config.json'}")
    launch_fit = find_launch_fit(scenario)
    if launch_fit is None:
        raise RecomputeError(
            f"run {run.id}: no launch fit for its scenario (its target and launch settings) in "
            "this workspace: run `ovtraj launch-fit` on the scenario first"
        )
    samples = run.samples()
    samples = samples[samples["sample_id"].isin(chosen)].reset_index(drop=True)
    records = evaluate_batch(MissionContext(scenario, launch_fit), samples)
    rows, _ = result_rows(list(zip(samples["sample_id"].astype(int), records, strict=True)))
    report = RecomputeReport(run.id, chosen, run.manifest.get("code_version"), code_version())
    for name in COMPARED_DATASETS:
        stored = run.totals() if name == "totals" else run.stage(name.split("/", 1)[1])
        stored = stored[stored["sample_id"].isin(chosen)]
        again = table_from_rows(rows.get(name, []), DATASETS[name], name).to_pandas()
        report.checks += _compare(name, stored, again, tolerances)
    return report


def _columns(dataset: str) -> list[str]:
    """The compared columns of a dataset: numbers and :data:`EXACT_TEXT` (not the key)."""
    schema = DATASETS[dataset]
    return [
        f.name
        for f in schema
        if f.name != "sample_id"
        and (
            pa.types.is_floating(f.type)
            or pa.types.is_integer(f.type)
            or pa.types.is_boolean(f.type)
            or f.name in EXACT_TEXT
        )
    ]


def _tolerance(settings: RecomputeSettings, column: str) -> tuple[str, float | None]:
    if column == "feasible" or column in EXACT_TEXT:
        return "", 0.0
    try:
        return settings.tolerance(column)
    except KeyError:
        raise RecomputeError(
            f"configs/{FILE}: no recompute tolerance for the column {column!r} (by its unit "
            "under recompute.tolerances, or by its name under recompute.columns)"
        ) from None


def _compare(
    dataset: str,
    stored: pd.DataFrame,
    again: pd.DataFrame,
    tolerances: dict[str, tuple[str, float | None]],
) -> list[ColumnCheck]:
    """Each compared column of one dataset; the samples present in one and not the other
    (a stage reached in one evaluation only) are a check of their own, ``rows``."""
    stored_ids, again_ids = set(stored["sample_id"]), set(again["sample_id"])
    checks = [ColumnCheck(dataset, "rows", "", float(len(stored_ids ^ again_ids)), 0.0, True)]
    both = stored.merge(again, on="sample_id", suffixes=("", " again"), how="inner")
    for column in _columns(dataset):
        unit, tolerance = tolerances[column]
        a, b = both[column], both[f"{column} again"]
        if column == "feasible" or column in EXACT_TEXT:
            differ = ~((a == b) | (a.isna() & b.isna()))
            checks.append(ColumnCheck(dataset, column, unit, float(differ.sum()), 0.0, True))
            continue
        x, y = a.to_numpy(dtype=float, na_value=np.nan), b.to_numpy(dtype=float, na_value=np.nan)
        missing = np.isnan(x) != np.isnan(y)
        compared = ~np.isnan(x) & ~np.isnan(y)
        # equal values differ by 0 (infinities too); unequal ones by |x - y|
        differences = np.where(x[compared] == y[compared], 0.0, np.abs(x[compared] - y[compared]))
        largest = float(np.max(differences)) if compared.any() else 0.0
        if missing.any():
            largest = math.inf
        checks.append(ColumnCheck(dataset, column, unit, largest, tolerance))
    return checks
