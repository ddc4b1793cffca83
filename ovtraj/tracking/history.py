"""The re-plan history of a target: one row per stored plan, in the order of the element
sets they were planned from, with the plan's key figures and its Monte Carlo's.

Rows come from the catalog (:mod:`ovtraj.tracking.catalog`): a plan's row holds its
figures as the plan file states them, so the history equals the plans; a plan Monte Carlo
(the latest complete one of the plan) adds its landing-miss p95 and dV margin. A pruned
child run does not remove a plan: plans live in their DoE run's pipeline folder.
"""

from __future__ import annotations

from typing import Any

import pandas as pd

from ovtraj.store.files import json_data
from ovtraj.tracking.catalog import Catalog
from ovtraj.tracking.catalog_schema import checked_id

__all__ = ["HISTORY_COLUMNS", "history", "previous_plan"]

# The columns of a history row (units in the names).
HISTORY_COLUMNS = (
    "element_set_epoch_utc",
    "plan_id",
    "pipeline_id",
    "doe_run",
    "run_id",
    "code_version",
    "launch_epoch_utc",
    "dv_total_mps",
    "t_total_s",
    "m_load_kg",
    "landing_miss_m",
    "mc_runs",
    "mc_landing_miss_p95_m",
    "mc_dv_margin_p95_mps",
    "created_utc",
    "target",
    "scenario",
    "source",
)
# The columns of a history row that name another item: ids, as the catalog file gives them.
_ID_COLUMNS = ("plan_id", "pipeline_id", "doe_run", "run_id")


def _monte_carlo(frame: pd.DataFrame) -> pd.DataFrame:
    """The latest complete Monte Carlo of each plan (by plan id)."""
    runs = frame[(frame["kind"] == "monte_carlo") & (frame["status"] == "complete")]
    runs = runs.sort_values(["created_utc", "id"]).drop_duplicates("plan_id", keep="last")
    return runs.set_index("plan_id")[["mc_runs", "mc_landing_miss_p95_m", "mc_dv_margin_p95_mps"]]


def history(
    catalog: Catalog,
    *,
    target: str | None = None,
    scenario: str | None = None,
    tags: dict[str, str] | None = None,
) -> pd.DataFrame:
    """The plans of ``target`` (its name), ``scenario`` (its name) and carrying ``tags``
    (every one), oldest element set first (then oldest pipeline, then plan id).
    :class:`~ovtraj.store.files.StoreError` naming the catalog file and the column when a
    row's id is not an id of the store."""
    frame = catalog.frame
    plans = frame[(frame["kind"] == "plan") & frame["error"].isna()].copy()
    if target is not None:
        plans = plans[plans["target"] == target]
    if scenario is not None:
        plans = plans[plans["scenario"] == scenario]
    for key, value in (tags or {}).items():
        plans = plans[[_tags(t).get(key) == value for t in plans["tags"]]]
    plans = plans.drop(
        columns=["plan_id", "mc_runs", "mc_landing_miss_p95_m", "mc_dv_margin_p95_mps"]
    )
    plans = plans.join(_monte_carlo(frame), on="id")
    plans = plans.rename(columns={"id": "plan_id"})
    plans = plans.sort_values(
        ["element_set_epoch_utc", "created_utc", "plan_id"], na_position="first"
    )
    for column in _ID_COLUMNS:  # each checked as an id typed on the command line
        for value in plans[column]:
            if value is not None:
                checked_id(value, f"{catalog.path}: {column}")
    return plans[list(HISTORY_COLUMNS)].reset_index(drop=True)


def previous_plan(catalog: Catalog, plan: dict[str, Any]) -> pd.Series | None:
    """The plan of the same target planned before ``plan`` (the history's row before the
    first row of another pipeline that ``plan`` would take), None when it is the first."""
    from ovtraj.tracking.catalog_rows import plan_values

    values = plan_values(plan)
    rows = history(catalog, target=values["target"])
    rows = rows[rows["pipeline_id"] != values["pipeline_id"]]
    key = (values["element_set_epoch_utc"] or "",)
    earlier = rows[[(e or "",) < key for e in rows["element_set_epoch_utc"]]]
    return None if not len(earlier) else earlier.iloc[-1]


def _tags(text: str) -> dict[str, Any]:
    """A catalog row's tags (a JSON object; anything else in a catalog read without a store
    key counts as no tags)."""
    try:
        found = json_data(text)
    except ValueError:
        return {}
    return found if isinstance(found, dict) else {}
