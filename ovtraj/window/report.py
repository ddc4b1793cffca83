"""A window's own files: the tables, the plots, the HTML page, ``window.json``.

In ``<run store>/windows/<window id>/``, one stored product (:class:`ovtraj.store.products.
Product`): ``window.parquet`` (:data:`WINDOW_SCHEMA`, a row per launch day), ``window.png``
and ``window.svg`` (T_total, dV_total and M_load of each day's picked plan against the
launch day, the best day marked), ``porkchop.parquet`` (:data:`ovtraj.window.porkchop.
PORKCHOP_SCHEMA`, each planned day's plan swept along one design variable),
``porkchop.png`` and ``porkchop.svg`` (dV_total and T_total as filled contours over the
launch day and that variable, each day's plan marked, the best day's a red star; drawn
from ``porkchop.parquet`` and ``window.parquet`` alone, :func:`porkchop_figure_of`),
``window.html`` (the table, each day's report linked by a relative link, the plots),
then ``window.json`` written last with their digests. The files hold stored results only
(no wall clock, no host, no absolute path): the same scan gives the same bytes, and a
scan whose files are stored is not written again.
"""

from __future__ import annotations

import html
import io
import logging
import math
import posixpath
import re
from collections.abc import Sequence
from dataclasses import asdict
from datetime import datetime, timedelta
from typing import Any

import pandas as pd

from ovtraj.config import Scenario
from ovtraj.formatting import number
from ovtraj.mission import DESIGN_NAMES
from ovtraj.optimize import Normalisation
from ovtraj.pipeline.pick import pick_weights
from ovtraj.pipeline.report import STYLE as REPORT_STYLE  # the pipeline report's look
from ovtraj.plots.embed import png_data_uri
from ovtraj.plots.front import axis_label
from ovtraj.plots.launch_days import mark_days_without_plan
from ovtraj.plots.porkchop import porkchop_figure
from ovtraj.plots.render import figure, png_bytes
from ovtraj.runs import RunStore
from ovtraj.store.files import StoreError, marker_files, remove_file
from ovtraj.store.products import Product
from ovtraj.store.records import BOOL, FLOAT, INT, TEXT, record_schema, table_from_rows
from ovtraj.store.verification import VerifyReport
from ovtraj.units import S_PER_HOUR
from ovtraj.window.porkchop import PORKCHOP_SCHEMA, Sweep, porkchop_grid, porkchop_rows
from ovtraj.window.records import (
    DAYS_DIR,
    FORMAT,
    PLANNED,
    WindowOutcome,
    best_day,
    plan_problem,
    record_problem,
    stored_day,
)

__all__ = [
    "WINDOW_SCHEMA",
    "load_window",
    "porkchop_figure_of",
    "verify_window",
    "window_figure",
    "window_rows",
    "write_window",
]

logger = logging.getLogger(__name__)

KIND = "launch-window"
MARKER = "window.json"
TABLE, PNG, SVG, PAGE = "window.parquet", "window.png", "window.svg", "window.html"
PORKCHOP, PORKCHOP_PNG, PORKCHOP_SVG = "porkchop.parquet", "porkchop.png", "porkchop.svg"
FILES = (TABLE, PNG, SVG, PORKCHOP, PORKCHOP_PNG, PORKCHOP_SVG, PAGE)

WINDOW_SCHEMA = record_schema(
    [
        ("day", INT),  # days after the scenario's launch day
        ("date", TEXT),  # the launch day, YYYY-MM-DD (UTC)
        ("status", TEXT),  # "planned" or "no plan"
        ("reason", TEXT),  # why a day has no plan
        ("t_total_h", FLOAT),  # the picked front point's objectives (the pick's values)
        ("dv_total_mps", FLOAT),
        ("m_load_kg", FLOAT),
        ("score", FLOAT),  # weighted mean of the normalised objectives: 0 ideal, 1 reference
        *[(name, FLOAT) for name in DESIGN_NAMES],  # the picked plan's design
        ("converged", BOOL),  # the day's verification loop
        ("best", BOOL),  # the day whose picked plan scores lowest
        ("doe_run", TEXT),
        ("pipeline_id", TEXT),
        ("plan", TEXT),  # the plan's JSON, relative to the run store's root
        ("report", TEXT),  # the plan's HTML report, relative to the run store's root
    ],
    required=("day", "date", "status", "best"),
)
"""``window.parquet``: a row per launch day, in day order."""

SCHEMAS = {TABLE: WINDOW_SCHEMA, PORKCHOP: PORKCHOP_SCHEMA}  # the tables' declared schemas


def window_rows(records: Sequence[dict[str, Any]], best: int | None) -> list[dict[str, Any]]:
    """The table's rows (:data:`WINDOW_SCHEMA`) of the day records."""
    rows = []
    for r in records:
        t_total = r["t_total_s"]
        rows.append(
            {
                "day": r["day"],
                "date": r["date"],
                "status": r["status"],
                "reason": r["reason"],
                "t_total_h": None if t_total is None else t_total / S_PER_HOUR,
                "dv_total_mps": r["dv_total_mps"],
                "m_load_kg": r["m_load_kg"],
                "score": r["score"],
                **{name: r[name] for name in DESIGN_NAMES},
                "converged": r["converged"],
                "best": r["day"] == best,
                "doe_run": r["doe_run"],
                "pipeline_id": r["pipeline_id"],
                "plan": r["plan"],
                "report": r["report"],
            }
        )
    return rows


def window_figure(
    records: Sequence[dict[str, Any]], best: int | None, normalisation: Normalisation, title: str
) -> Any:
    """T_total, dV_total and M_load of each day's picked plan against the launch day (three
    panels, one time axis); a day with no plan is a grey cross on the axis, the best day a
    red star with a dashed line through the panels."""
    from matplotlib.dates import DateFormatter, DayLocator

    fig = figure((9.0, 8.0))
    axes = fig.subplots(len(normalisation.objectives), 1, sharex=True)
    days = [datetime.fromisoformat(r["date"]) for r in records]  # 0 h UTC of each day
    missing = [k for k, r in enumerate(records) if r["status"] != PLANNED]
    for ax, objective in zip(axes, normalisation.objectives, strict=True):
        # NaN for a day with no plan: the line breaks there
        y = [
            math.nan if r["status"] != PLANNED else r[objective.name] * objective.report_scale
            for r in records
        ]
        ax.plot(days, y, marker="o", color="tab:blue", label="picked plan of the day")
        if missing:
            mark_days_without_plan(ax, [days[k] for k in missing])
        if best is not None:
            value = records[best][objective.name] * objective.report_scale
            ax.axvline(days[best], color="tab:red", linestyle="--", linewidth=1.0)
            ax.plot(
                [days[best]],
                [value],
                linestyle="none",
                marker="*",
                markersize=16,
                color="tab:red",
                label=f"best day {records[best]['date']}",
            )
        ax.set_ylabel(axis_label(objective, "y"))
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    # A tick per day up to ~12 days, then every few days; half a day of margin each side.
    axes[-1].xaxis.set_major_locator(DayLocator(interval=max(1, -(-len(days) // 12))))
    axes[-1].xaxis.set_major_formatter(DateFormatter("%Y-%m-%d"))
    axes[-1].set_xlim(days[0] - timedelta(hours=12), days[-1] + timedelta(hours=12))
    axes[-1].set_xlabel("launch day (UTC)")
    fig.autofmt_xdate()
    fig.suptitle(title, fontsize=10)
    return fig


# The porkchop's panels: the table column and the objective it holds.
PORKCHOP_PANELS = (("dv_total_mps", "dv_total_mps"), ("t_total_h", "t_total_s"))


def porkchop_figure_of(
    window: pd.DataFrame,
    porkchop: pd.DataFrame,
    sweep: Sweep,
    normalisation: Normalisation,
    title: str,
) -> Any:
    """The porkchop (:func:`ovtraj.plots.porkchop.porkchop_figure`) of the stored tables
    alone: ``porkchop.parquet``'s sweep as dV_total and T_total contours over the days of
    ``window.parquet``, each planned day's plan at its value of the variable, the best
    day's a red star."""
    objectives = {objective.name: objective for objective in normalisation.objectives}
    dates = list(window["date"])
    grid = porkchop_grid(porkchop, dates, sweep, [column for column, _ in PORKCHOP_PANELS])
    panels = {}
    for column, name in PORKCHOP_PANELS:
        objective = objectives[name]
        better = "lower" if objective.sense > 0 else "higher"
        label = f"{objective.label} [{objective.report_unit}] ({better} is better)"
        panels[label] = grid.objectives[column]
    planned = window[window["status"] == PLANNED]
    chosen = {int(row.day): float(getattr(row, sweep.variable)) for row in planned.itertuples()}
    best = window.loc[window["best"], "day"]
    return porkchop_figure(
        dates,
        grid.values,
        f"{sweep.variable} (the day's plan, swept)",
        panels,
        chosen=chosen,
        best=int(best.iloc[0]) if len(best) else None,
        infeasible=grid.infeasible,
        title=title,
    )


_CLIP_ID = re.compile(rb"\bp[0-9a-f]{10}\b")


def svg_bytes(fig: Any) -> bytes:
    """The figure as SVG bytes that depend only on what is drawn: no date or creator in
    the metadata, ids from a fixed salt, and the clip paths' ids (matplotlib hashes the
    clip object's text, its memory address in it) numbered in order of appearance."""
    from matplotlib import rc_context

    buffer = io.BytesIO()
    with rc_context({"svg.hashsalt": KIND}):
        fig.savefig(buffer, format="svg", metadata={"Date": None, "Creator": None})
    numbered: dict[bytes, bytes] = {}

    def number_of(found: re.Match[bytes]) -> bytes:
        return numbered.setdefault(found.group(0), b"clip%d" % len(numbered))

    return _CLIP_ID.sub(number_of, buffer.getvalue())


def _porkchop_title(base: Scenario, records: Sequence[dict[str, Any]], sweep: Sweep) -> str:
    span = f"{records[0]['date']} to {records[-1]['date']} ({len(records)} days)"
    return (
        f"porkchop of {base.name}: {span}\n"
        f"each day's plan with {sweep.variable} at {len(sweep.values)} values, the rest kept"
    )


def _title(base: Scenario, records: Sequence[dict[str, Any]], best: int | None) -> str:
    span = f"{records[0]['date']} to {records[-1]['date']} ({len(records)} days)"
    if best is None:
        return f"launch window of {base.name}: {span}, no day planned"
    return (
        f"launch window of {base.name}: {span}\n"
        f"best day {records[best]['date']} (score {records[best]['score']:.4f})"
    )


def _cell(value: Any, digits: int = 4) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return html.escape(number(value, digits=digits))
    return html.escape(str(value))


def window_page(
    base: Scenario,
    records: Sequence[dict[str, Any]],
    best: int | None,
    weights: Sequence[float],
    plot_png: Any,
    window_dir: str,
    porkchop_png: Any,
    sweep: Sweep,
) -> bytes:
    """The window's HTML page: the verdict, the table (each day's report and plan linked
    relative to ``window_dir``, the window's folder relative to the run store's root), the
    plots embedded (each SVG beside it)."""
    optimize = base.mission.optimize
    title = f"ovtraj launch window: {base.name}"
    shown_weights = ", ".join(f"{w:g}" for w in weights)
    ideal = ", ".join(f"{k} {v:g}" for k, v in optimize.ideal.model_dump().items())
    reference = ", ".join(f"{k} {v:g}" for k, v in optimize.reference.model_dump().items())
    parts = [
        "<!doctype html><html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{REPORT_STYLE}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f"<p>{len(records)} launch days from {html.escape(records[0]['date'])}: each day's "
        "whole-mission pipeline, its plan picked from its verified front by the lowest "
        f"weighted mean of the normalised objectives (weights T, dV, M = {shown_weights}; 0 "
        f"the ideal point: {html.escape(ideal)}; 1 the reference point: "
        f"{html.escape(reference)}; mission.optimize). The best day's plan scores lowest.</p>",
        _verdict(records, best),
        "<h2>Days</h2>",
        _days_table(records, best, window_dir),
        "<h2>T_total, dV_total and M_load against the launch day</h2>",
        f"<figure><img alt='{PNG}' src='{png_data_uri(plot_png)}'>"
        f"<figcaption><a href='{SVG}'>{SVG}</a></figcaption></figure>",
        "<h2>Porkchop: dV_total and T_total over the launch day and "
        f"{html.escape(sweep.variable)}</h2>",
        f"<p>Each planned day's plan evaluated again by the mission chain with "
        f"{html.escape(sweep.variable)} at {len(sweep.values)} values from "
        f"{sweep.values[0]:g} to {sweep.values[-1]:g} (mission.design_bounds), its other "
        "design variables kept (configs/window.yaml porkchop; the values in "
        f"<a href='{PORKCHOP}'>{PORKCHOP}</a>). A column is one day's plan varied; the "
        "contours between days interpolate between the plans of different days. Circles: "
        "each day's plan; the star: the best day's; dots: infeasible designs.</p>",
        f"<figure><img alt='{PORKCHOP_PNG}' src='{png_data_uri(porkchop_png)}'>"
        f"<figcaption><a href='{PORKCHOP_SVG}'>{PORKCHOP_SVG}</a></figcaption></figure>",
        "</body></html>\n",
    ]
    return "\n".join(parts).encode("utf-8")


def _verdict(records: Sequence[dict[str, Any]], best: int | None) -> str:
    """The page's verdict: the best day with its plan's objectives and score, or none."""
    if best is None:
        return "<p class='verdict no'>no day has a plan.</p>"
    r = records[best]
    return (
        f"<p class='verdict ok'>best day {html.escape(r['date'])} (day {r['day']}): "
        f"T_total {_cell(r['t_total_s'] / S_PER_HOUR)} h, dV_total {_cell(r['dv_total_mps'])} "
        f"m/s, M_load {_cell(r['m_load_kg'])} kg, score {r['score']:.4f}.</p>"
    )


def _days_table(records: Sequence[dict[str, Any]], best: int | None, window_dir: str) -> str:
    """A row per day (the best in bold): its objectives, score, verdict, its report and
    plan linked relative to ``window_dir``, and why it has no plan."""
    head = (
        "<tr><th>day</th><th>date</th><th>T_total [h]</th><th>dV_total [m/s]</th>"
        "<th>M_load [kg]</th><th>score</th><th>converged</th><th>report</th><th>plan</th>"
        "<th>note</th></tr>"
    )
    rows = []
    for r in records:
        mark = " style='font-weight:bold'" if r["day"] == best else ""
        links = ["-", "-"]
        for k, key in enumerate(("report", "plan")):
            if r[key] is not None:
                href = html.escape(posixpath.relpath(r[key], window_dir), quote=True)
                links[k] = f"<a href='{href}'>{html.escape(posixpath.basename(r[key]))}</a>"
        t_total = None if r["t_total_s"] is None else r["t_total_s"] / S_PER_HOUR
        note = "best day" if r["day"] == best else (r["reason"] or "")
        cells = (
            str(r["day"]),
            html.escape(r["date"]),
            _cell(t_total),
            _cell(r["dv_total_mps"]),
            _cell(r["m_load_kg"]),
            "-" if r["score"] is None else f"{r['score']:.4f}",
            _cell(r["converged"]),
            *links,
            html.escape(note),
        )
        rows.append(f"<tr{mark}>{''.join(f'<td>{c}</td>' for c in cells)}</tr>")
    return f"<table><thead>{head}</thead><tbody>{''.join(rows)}</tbody></table>"


def write_window(
    directory: Any,
    identity: str,
    base: Scenario,
    request: Any,
    code: str,
    records: Sequence[dict[str, Any]],
    best: int | None,
    store: RunStore,
    sweep: Sweep,
) -> WindowOutcome:
    """Write the window's files, ``window.json`` last (module notes); the same scan
    writes the same bytes, which a stored product takes as a no-op."""
    normalisation = Normalisation.mission(base.mission.optimize)
    weights = pick_weights(request.pick)
    table = table_from_rows(window_rows(records, best), WINDOW_SCHEMA, "launch window")
    fig = window_figure(records, best, normalisation, _title(base, records, best))
    png, svg = png_bytes(fig), svg_bytes(fig)
    sweeps = table_from_rows(porkchop_rows(records), PORKCHOP_SCHEMA, "porkchop")
    # Drawn from the tables as stored (read back the way a reader gets them).
    title = _porkchop_title(base, records, sweep)
    fig = porkchop_figure_of(table.to_pandas(), sweeps.to_pandas(), sweep, normalisation, title)
    porkchop_png, porkchop_svg = png_bytes(fig), svg_bytes(fig)
    window_dir = posixpath.relpath(str(directory), str(store.root))
    product = Product(directory, MARKER)
    with product.writing() as out:
        out.write_table(TABLE, table, WINDOW_SCHEMA)
        out.write_bytes(PNG, png)
        out.write_bytes(SVG, svg)
        out.write_table(PORKCHOP, sweeps, PORKCHOP_SCHEMA)
        out.write_bytes(PORKCHOP_PNG, porkchop_png)
        out.write_bytes(PORKCHOP_SVG, porkchop_svg)
        page = window_page(
            base,
            records,
            best,
            weights,
            directory / PNG,
            window_dir,
            directory / PORKCHOP_PNG,
            sweep,
        )
        out.write_bytes(PAGE, page)
        out.finish(
            {
                "format": FORMAT,
                "kind": KIND,
                "window_id": identity,
                "scenario": base.name,
                "days": len(records),
                "first_date": records[0]["date"],
                "last_date": records[-1]["date"],
                "samples": None if request.samples is None else int(request.samples),
                "seed": None if request.seed is None else int(request.seed),
                "pick": asdict(request.pick),
                "weights": [float(w) for w in weights],
                "code": code,
                "planned_days": sum(1 for r in records if r["status"] == PLANNED),
                "best_day": best,
                "best_date": None if best is None else records[best]["date"],
                "porkchop": sweep.as_data(),
            }
        )
    files = {name: directory / name for name in (*FILES, MARKER)}
    return WindowOutcome(identity, directory, list(records), best, files, reused=False)


def load_window(
    directory: Any, identity: str, dates: Sequence[str], store: RunStore, sweep: Sweep
) -> WindowOutcome | None:
    """The stored window when it checks: ``window.json`` (its seal, the scan it names) and
    every file it lists (size, SHA-256, the table's schema), every day's record and the
    plan each names. None when there is none; a stored one that fails is removed (with a
    warning naming the cause), so the scan writes it again."""
    product = Product(directory, MARKER)
    if not product.exists():
        return None
    try:
        marker = product.marker()
        expected = {"format": FORMAT, "kind": KIND, "window_id": identity, "days": len(dates)}
        wrong = [key for key, value in expected.items() if marker.get(key) != value]
        if wrong:
            raise StoreError(f"{product.marker_path}: not this scan ({', '.join(wrong)})")
        for name in FILES:
            product.read_bytes(name, marker)
        for name, schema in SCHEMAS.items():
            product.read_table(name, schema, marker)
        records = [
            stored_day(directory, identity, d, dates[d], store, sweep) for d in range(len(dates))
        ]
        if any(record is None for record in records):
            raise StoreError(f"{directory}: a day's record or plan changed")
        best = best_day(records)
        if marker.get("best_day") != best:
            raise StoreError(f"{product.marker_path}: best_day is not its days' best")
    except StoreError as err:
        logger.warning("%s; the window is written again", err)
        for name in (MARKER, *FILES):
            remove_file(directory / name)
        return None
    files = {name: directory / name for name in (*FILES, MARKER)}
    return WindowOutcome(identity, directory, records, best, files, reused=True)


def verify_window(directory: Any, store: RunStore) -> VerifyReport:
    """Check a stored window (like fsck, nothing removed): ``window.json``'s seal (with a
    store key) and each file it lists against its size, SHA-256 and the table's schema;
    every day's record (its seal, its fields, the plan bytes it names); files nothing
    lists reported as uncovered."""
    report = VerifyReport(directory.name)
    marker_path = directory / MARKER
    covered = {marker_path}
    marker = report.read_document(marker_path)
    if marker is None:
        return report
    try:
        listed = marker_files(marker_path, marker)
    except StoreError as err:
        report.problems.append(str(err))
        return report
    for name, digest in listed.items():
        covered.add(directory / name)
        report.check_file(directory / name, digest, SCHEMAS.get(name))
    identity = marker.get("window_id")
    for path in sorted((directory / DAYS_DIR).glob("*.json")):
        covered.add(path)
        record = report.read_document(path)
        if record is None:
            continue
        day = int(path.stem) if path.stem.isdigit() else -1
        date = record.get("date") if isinstance(record, dict) else None
        date = date if isinstance(date, str) else ""  # a record without one fails below
        problem = record_problem(record, identity, day, date) or plan_problem(record, store)
        if problem:
            report.problems.append(f"{path}: {problem}")
    report.find_uncovered(directory, covered)
    return report
