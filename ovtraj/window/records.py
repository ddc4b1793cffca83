"""A window's day records: one JSON per launch day in ``<window>/days/``, what it holds,
how it is checked when read again, the best day of a set of them and what they say
together about convergence (:func:`window_verdict`, the verdict ``ovtraj window`` prints and
the window flow's state carries).

A record is written (sealed when a store key is configured) as its day's pipeline ends,
so a scan stopped half-way resumes with the days it has. Read again, nothing of it is
trusted: every field is checked, and a planned day's plan file must still hold the bytes
the record names (a pruned or rewritten plan: the day runs again, its pipeline reusing
what the run store holds).
"""

from __future__ import annotations

import logging
import math
import posixpath
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ovtraj.mission import DESIGN_NAMES
from ovtraj.runs import RunStore
from ovtraj.runs.ids import checked_id
from ovtraj.store.files import StoreError, file_digest, remove_file
from ovtraj.store.seals import read_authenticated, write_sealed
from ovtraj.window.porkchop import Sweep, sweep_problem

__all__ = [
    "DAY_KEYS",
    "NO_PLAN",
    "PLANNED",
    "WindowOutcome",
    "best_day",
    "new_record",
    "plan_problem",
    "record_problem",
    "relative_path",
    "stored_day",
    "window_verdict",
    "write_day",
]

logger = logging.getLogger(__name__)

FORMAT = 3  # 2: a planned day's record holds its pipeline's verdict; 3: its design, its sweep
DAY_KIND = "launch-window-day"
DAYS_DIR = "days"
PLANNED, NO_PLAN = "planned", "no plan"
ID_FIELDS = ("doe_run", "pipeline_id", "final_run")
# The picked plan's front objectives (SI, as the front stores them), its score, its design.
NUMBER_FIELDS = ("t_total_s", "dv_total_mps", "m_load_kg", "score", *DESIGN_NAMES)
PATH_FIELDS = ("plan", "report")  # relative to the run store's root
DAY_KEYS = (
    "format",
    "kind",
    "window_id",
    "day",
    "date",
    "status",
    "reason",
    *ID_FIELDS,
    "converged",
    "stop_reason",
    "verdict",  # the day's pipeline's own sentence (PipelineOutcome.verdict)
    "front_index",
    "sample_id",
    *NUMBER_FIELDS,
    *PATH_FIELDS,
    "plan_sha256",
    "sweep",  # the plan swept along the porkchop's variable (ovtraj.window.porkchop)
)


@dataclass
class WindowOutcome:
    """A scan: its id and folder, every day's record (day order), the best day (None: no
    day planned), its files (name -> path) and whether it was stored already."""

    window_id: str
    directory: Any
    records: list[dict[str, Any]]
    best_day: int | None
    files: dict[str, Any]
    reused: bool

    @property
    def planned_days(self) -> int:
        return sum(1 for r in self.records if r["status"] == PLANNED)


def new_record(window_id: str, day: int, date: str) -> dict[str, Any]:
    """A day's record before its pipeline: no plan, nothing known yet."""
    record: dict[str, Any] = dict.fromkeys(DAY_KEYS)
    record.update(
        format=FORMAT, kind=DAY_KIND, window_id=window_id, day=day, date=date, status=NO_PLAN
    )
    return record


def relative_path(path: Any, root: Any) -> str:
    """``path`` relative to ``root`` (POSIX; of a folder or of an ``s3://`` URL)."""
    if isinstance(path, Path) and isinstance(root, Path):
        path, root = path.resolve(), root.resolve()
    return posixpath.relpath(str(path), str(root))


def best_day(records: Sequence[dict[str, Any]]) -> int | None:
    """The planned day with the lowest score (the earlier on a tie); None without one."""
    planned = [r for r in records if r["status"] == PLANNED]
    if not planned:
        return None
    return min(planned, key=lambda r: (r["score"], r["day"]))["day"]


def window_verdict(records: Sequence[dict[str, Any]]) -> tuple[bool, str]:
    """Whether every planned day's verification loop converged, and one line saying so:
    the days that did not, by date and number, else how many converged. A window with no
    planned day has not converged ("no day has a plan"). ``records``: day records, or rows
    with their ``day``, ``date``, ``status`` and ``converged``."""
    planned = [r for r in records if r["status"] == PLANNED]
    if not planned:
        return False, "no day has a plan"
    unconverged = [r for r in planned if not r["converged"]]
    if unconverged:
        days = ", ".join(f"{r['date']} (day {r['day']})" for r in unconverged)
        return False, f"not converged on {len(unconverged)} of {len(records)} days: {days}"
    shown = f"converged on {len(planned)} of {len(records)} days"
    missing = len(records) - len(planned)
    return True, shown + (f" ({missing} without a plan)" if missing else "")


def day_path(directory: Any, day: int) -> Any:
    return directory / DAYS_DIR / f"{day:04d}.json"


def write_day(directory: Any, record: dict[str, Any]) -> None:
    """Store a day's record (a record there that failed its checks is replaced)."""
    path = day_path(directory, record["day"])
    remove_file(path)
    write_sealed(path, record)


def stored_day(
    directory: Any, window_id: str, day: int, date: str, store: RunStore, sweep: Sweep
) -> dict[str, Any] | None:
    """The day's stored record when it checks (its seal, every field, the window's
    ``sweep``, its plan's bytes); None otherwise, with a warning naming the file when one
    is there."""
    path = day_path(directory, day)
    if not path.is_file():
        return None
    try:
        record = read_authenticated(path)
    except StoreError as err:
        logger.warning("%s; the day runs again", err)
        return None
    problem = record_problem(record, window_id, day, date, sweep) or plan_problem(record, store)
    if problem:
        logger.warning("%s: %s; the day runs again", path, problem)
        return None
    return {key: record[key] for key in DAY_KEYS}  # without the seal


def record_problem(
    record: Any, window_id: str, day: int, date: str, sweep: Sweep | None = None
) -> str | None:
    """Why ``record`` is not day ``day``'s record of window ``window_id`` (with ``sweep``:
    holding that sweep); None when it is."""
    if not isinstance(record, dict):
        return "not a JSON object"
    missing = [key for key in DAY_KEYS if key not in record]
    if missing:
        return f"lacks {', '.join(missing)}"
    expected = {"format": FORMAT, "kind": DAY_KIND, "window_id": window_id, "day": day}
    for key, value in (expected | {"date": date}).items():
        if type(record[key]) is not type(value) or record[key] != value:
            return f"{key} is not {value!r}"
    if record["status"] == NO_PLAN:
        if record["sweep"] is not None:
            return "a day with no plan has a sweep"
        return None if isinstance(record["reason"], str) else "a day with no plan gives no reason"
    if record["status"] != PLANNED:
        return f"status is neither {PLANNED!r} nor {NO_PLAN!r}"
    for key in ID_FIELDS:
        try:
            checked_id(record[key], key)
        except StoreError as err:
            return str(err)
    for key in NUMBER_FIELDS:
        if type(record[key]) is not float or not math.isfinite(record[key]):
            return f"{key} is not a finite number"
    for key in ("front_index", "sample_id"):
        if type(record[key]) is not int or record[key] < 0:
            return f"{key} is not a whole number"
    if type(record["converged"]) is not bool or not isinstance(record["stop_reason"], str):
        return "converged or stop_reason is missing"
    if not isinstance(record["verdict"], str):
        return "verdict is missing"
    for key in PATH_FIELDS:
        value = record[key]
        if not isinstance(value, str) or value.startswith("/") or ".." in value.split("/"):
            return f"{key} is not a path inside the run store"
    sha256 = record["plan_sha256"]
    if not isinstance(sha256, str) or len(sha256) != 64:
        return "plan_sha256 is not a SHA-256"
    return sweep_problem(record["sweep"], sweep)


def plan_problem(record: dict[str, Any], store: RunStore) -> str | None:
    """Why a planned day's plan file does not hold the bytes its record names (missing,
    changed); None when it does, or for a day with no plan."""
    if record["status"] != PLANNED:
        return None
    path = store.root / record["plan"]
    try:
        digest = file_digest(path)
    except StoreError as err:
        return str(err)
    if digest.sha256 != record["plan_sha256"]:
        return f"{path}: changed since the window recorded it"
    return None
