"""Two stored items compared figure by figure: only what differs, with the change and its unit.

The figures are :mod:`ovtraj.tracking.figures`'; two values differ when they are not equal
as stored (the store is deterministic: the same inputs give the same bytes, so an exact
comparison finds exactly the changed fields). The change of a number is ``B - A`` in the
figure's unit, of an epoch ``B - A`` in seconds; text and lists have none.
"""

from __future__ import annotations

import datetime
import math
from dataclasses import asdict, dataclass
from typing import Any

from ovtraj.config.io_limits import shown_text
from ovtraj.formatting import duration, quantity
from ovtraj.tracking.figures import INPUTS, RESULTS, Figure
from ovtraj.units import S_PER_HOUR

__all__ = ["Change", "changes", "markdown_table", "text_rows"]

_LIST_CHARS = 100  # a list (a TLE's lines) shown in a table is cut here; --json has it whole


@dataclass(frozen=True)
class Change:
    """One figure of both items: ``a`` and ``b`` (None when the item has no such figure),
    ``change`` (``b - a`` for numbers and epochs [s], else None), ``changed``."""

    group: str
    name: str
    unit: str
    a: Any
    b: Any
    change: float | None
    changed: bool

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def _epoch(value: Any) -> datetime.datetime | None:
    if not isinstance(value, str):
        return None
    try:
        parsed = datetime.datetime.fromisoformat(value.strip())
    except ValueError:
        return None
    return parsed if parsed.tzinfo is not None else parsed.replace(tzinfo=datetime.UTC)


def _difference(unit: str, a: Any, b: Any) -> float | None:
    if unit == "utc":
        ta, tb = _epoch(a), _epoch(b)
        return None if ta is None or tb is None else (tb - ta).total_seconds()
    na, nb = _number(a), _number(b)
    if na is None or nb is None or not (math.isfinite(na) and math.isfinite(nb)):
        return None
    return nb - na


def changes(a: list[Figure], b: list[Figure], *, everything: bool = False) -> list[Change]:
    """The figures of ``a`` and ``b`` that differ (with ``everything``, all of them), inputs
    first, each group in name order; a figure only one side has counts as changed."""
    left = {(f.group, f.name): f for f in a}
    right = {(f.group, f.name): f for f in b}
    order = {INPUTS: 0, RESULTS: 1}
    found = []
    for key in sorted(left.keys() | right.keys(), key=lambda k: (order.get(k[0], 2), k[1])):
        fa, fb = left.get(key), right.get(key)
        va = fa.value if fa is not None else None
        vb = fb.value if fb is not None else None
        changed = fa is None or fb is None or va != vb or type(va) is not type(vb)
        if not (changed or everything):
            continue
        unit = (fa or fb).unit  # type: ignore[union-attr]
        delta = _difference(unit, va, vb) if changed else 0.0 if _number(va) is not None else None
        found.append(Change(key[0], key[1], unit, va, vb, delta, changed))
    return found


def _shown(value: Any, unit: str) -> str:
    if isinstance(value, list):
        text = ", ".join(str(v) for v in value)
        return text if len(text) <= _LIST_CHARS else text[: _LIST_CHARS - 3] + "..."
    if isinstance(value, bool) or value is None:
        return "-" if value is None else str(value).lower()
    return quantity(value, "" if unit == "" else unit)


def _shown_change(change: Change) -> str:
    if change.change is None:
        return ""
    if change.unit in ("utc", "s") and abs(change.change) >= S_PER_HOUR:
        sign = "+" if change.change >= 0 else "-"
        return sign + duration(abs(change.change))
    if change.unit == "utc":
        return f"{change.change:+.6g} s"
    return f"{change.change:+.6g}" + (f" {change.unit}" if change.unit else "")


def text_rows(found: list[Change]) -> list[tuple[str, str, str, str, str]]:
    """(group, field, A, B, change) of each change, values with their units; a field's
    name and a text value are stored text, shown escaped and cut (:func:`shown_text`)."""
    return [
        (
            c.group,
            shown_text(c.name),
            shown_text(_shown(c.a, c.unit)),
            shown_text(_shown(c.b, c.unit)),
            _shown_change(c),
        )
        for c in found
    ]


def markdown_table(found: list[Change], a_label: str, b_label: str) -> str:
    """A Markdown table of the changes (to paste in a review or a ticket)."""

    def cell(text: str) -> str:
        return text.replace("|", "\\|").replace("\n", " ")

    lines = [
        f"| group | field | A: {cell(a_label)} | B: {cell(b_label)} | change |",
        "|---|---|---|---|---|",
    ]
    for row in text_rows(found):
        lines.append("| " + " | ".join(cell(x) for x in row) + " |")
    return "\n".join(lines)
