"""What a pipeline result means, in words and in one self-contained HTML report.

:func:`stop_explanation` says whether the verification loop converged and why it stopped;
:func:`pick_explanation` why the planned point was chosen; :func:`write_report` writes
``<plan>-report.html`` next to the plan: the verdict, the rounds, the surrogates'
validation, the verified front, the plan's key figures, its path peaks against their
limits, its manoeuvres, the ascent from the drop, the entry's time histories, the flights
of the plan stored beside it (:mod:`.report_tables`, :mod:`.plan_flights`) and every plot,
embedded (``data:`` URIs), so the file can be mailed or opened on another machine. The
report holds only stored results (no wall clock, no host): the same plan and flights give
the same bytes.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.config import scenario_from_dict
from ovtraj.formatting import number, utc
from ovtraj.optimize import Normalisation
from ovtraj.pipeline.features import PASS_MODEL, unregressed
from ovtraj.pipeline.pick import Pick, pick_weights, weighted_scores
from ovtraj.pipeline.report_tables import flight_shown, manoeuvres_shown, margins_shown
from ovtraj.plots.embed import png_data_uri
from ovtraj.store.files import write_bytes
from ovtraj.units import M_PER_KM, S_PER_HOUR

__all__ = [
    "FLOWN_END",
    "FLOWN_START",
    "STYLE",
    "flown_section",
    "pick_explanation",
    "stop_explanation",
    "write_report",
]

# Outputs the surrogates model without a regressor, and how (ovtraj/pipeline/features.py).
_UNREGRESSED = {
    PASS_MODEL: " (the deorbit's pass predicted in closed form from the design, plus the "
    "samples' median offset; docs/optimize.md)"
}

_STOPS = {
    "converged": "converged: every front point verified in the last round is feasible and "
    "its predicted objectives are within {tolerance:.1%} of the objective span of the real "
    "chain's values",
    # With a hypervolume tolerance the loop converges only once the front is stable too.
    "converged and stable": "converged: every front point verified in the last round is "
    "feasible and its predicted objectives are within {tolerance:.1%} of the objective span of "
    "the real chain's values, and the round added {gain} to the verified front's hypervolume, "
    "under mission.verify.hypervolume_tolerance ({hypervolume_tolerance})",
    "front already evaluated": "converged: every point of the surrogate front has already "
    "been evaluated with the real chain",
    "front stable": "converged: the last round added {gain} to the verified front's "
    "hypervolume, under mission.verify.hypervolume_tolerance ({hypervolume_tolerance}): "
    "more infill no longer improves the real front (largest error on the front {error}, "
    "tolerance {tolerance:.1%})",
    "max_iterations": "not converged: stopped after {max_iterations} rounds "
    "(mission.verify.max_iterations) with a largest error of {error} on the front (the "
    "tolerance is {tolerance:.1%} of the objective span; an infeasible point counts 100 %). "
    "The verified front holds real values only, but the surrogates may still miss part of "
    "it",
    "budget": "not converged: the budget of {budget} real infill evaluations "
    "(mission.verify.budget) is spent, largest error {error} on the front (tolerance "
    "{tolerance:.1%})",
    "empty surrogate front": "not converged: NSGA-II found no surrogate point predicted "
    "feasible; the verified front comes from the DoE samples only",
}


# With mission.verify.promise_tolerance: what the last surrogates promise decides.
_PROMISE_STOPS = {
    "converged": "converged: the surrogates fitted on all {evaluations} real evaluations "
    "promise {promise} of hypervolume beyond the verified front, under "
    "mission.verify.promise_tolerance ({promise_tolerance})",
    "front already evaluated": "converged: every point of the surrogate front has already "
    "been evaluated with the real chain",
    "max_iterations": "not converged: stopped after {max_iterations} rounds "
    "(mission.verify.max_iterations) with the surrogates still promising {promise} of "
    "hypervolume beyond the verified front (tolerance {promise_tolerance}); the verified front "
    "holds real values only, but more of the front may lie where they point",
    "budget": "not converged: the budget of {budget} real infill evaluations "
    "(mission.verify.budget) is spent with the surrogates still promising {promise} of "
    "hypervolume beyond the verified front (tolerance {promise_tolerance})",
    "empty surrogate front": "not converged: NSGA-II found no surrogate point predicted "
    "feasible; the verified front comes from the DoE samples only",
}


def stop_explanation(summary: dict[str, Any], verify: Any) -> str:
    """One sentence: converged or not, and why the loop stopped (``verify``: the
    scenario's ``mission.verify`` settings), and the verified front's hypervolume against
    the direct reference's when the summary holds that ratio."""
    sentence = _stop_sentence(summary, verify)
    ratio = summary.get("reference_ratio")
    if ratio is None:
        return sentence
    return (
        f"{sentence}. Hypervolume {summary['hypervolume']:.4f}: {ratio:.3f} of the direct "
        f"reference front's {summary['reference_hypervolume']:.4f} "
        f"({summary['reference_evaluations']:,} real evaluations, data/reference/direct_front)"
    )


def _stop_sentence(summary: dict[str, Any], verify: Any) -> str:
    rounds = summary.get("iterations", [])
    promises = [i["promised_gain"] for i in rounds if i.get("promised_gain") is not None]
    if getattr(verify, "promise_tolerance", None) is not None and promises:
        real = summary.get("real_evaluations", {})
        template = _PROMISE_STOPS.get(summary["stop_reason"], "stopped: {reason}")
        return template.format(
            evaluations=int(real.get("doe", 0)) + int(real.get("infill", 0)),
            promise=f"{promises[-1]:.2%}",
            promise_tolerance=f"{verify.promise_tolerance:.2%}",
            max_iterations=verify.max_iterations,
            budget=verify.budget,
            reason=summary["stop_reason"],
        )
    errors = [i["max_error"] for i in rounds if "max_error" in i]
    gains = [i["hypervolume_gain"] for i in rounds if i.get("hypervolume_gain") is not None]
    tolerance = verify.hypervolume_tolerance
    reason = summary["stop_reason"]
    if reason == "converged" and tolerance is not None and gains:
        reason = "converged and stable"
    template = _STOPS.get(reason, "stopped: {reason}")
    return template.format(
        gain=f"{gains[-1]:.2%}" if gains else "-",
        hypervolume_tolerance="-" if tolerance is None else f"{tolerance:.2%}",
        tolerance=verify.tolerance,
        max_iterations=verify.max_iterations,
        budget=verify.budget,
        error=f"{errors[-1]:.1%}" if errors else "-",
        reason=summary["stop_reason"],
    )


def _objective_text(normalisation: Normalisation, row: pd.Series) -> str:
    return ", ".join(
        f"{o.label} {number(float(row[o.name]) * o.report_scale, digits=4)} {o.report_unit}"
        for o in normalisation.objectives
    )


def pick_explanation(
    front: pd.DataFrame, normalisation: Normalisation, pick: Pick, row: pd.Series
) -> str:
    """Why ``row`` (the result of ``pick_front_point``) is the planned point."""
    chosen = f"front point {int(row['front_index'])} ({_objective_text(normalisation, row)})"
    if pick.index is not None:
        return f"{chosen}: picked by its index on the front (--pick {pick.index})"
    weights = pick_weights(pick)
    limits = [
        f"{label} {sign} {value:g} {unit}"
        for label, sign, value, unit in (
            ("T_total", "<=", pick.max_t_total_h, "h"),
            ("dV_total", "<=", pick.max_dv_total_mps, "m/s"),
            ("M_load", ">=", pick.min_m_load_kg, "kg"),
        )
        if value is not None
    ]
    scores = weighted_scores(front, normalisation, weights)
    among = f"among the {len(front)} points of the verified front"
    if limits:
        among += f" that meet {' and '.join(limits)}"
    shown = ", ".join(f"{w:g}" for w in weights)
    return (
        f"{chosen}: the lowest weighted sum of the normalised objectives (weights T, dV, M = "
        f"{shown}; 0 is the ideal point, 1 the reference point) {among}, score "
        f"{scores[int(row['front_index'])]:.4f}"
    )


def _table(frame: pd.DataFrame) -> str:
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in frame.columns)
    rows = []
    for values in frame.itertuples(index=False):
        cells = []
        for value in values:
            if value is None or (np.ndim(value) == 0 and pd.isna(value)):
                text = "-"
            elif isinstance(value, float | np.floating):
                text = number(float(value), digits=4)
            else:
                text = str(value)
            cells.append(f"<td>{html.escape(text)}</td>")
        rows.append(f"<tr>{''.join(cells)}</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>"


def _front_frame(front: pd.DataFrame, normalisation: Normalisation) -> pd.DataFrame:
    shown = front[["front_index", "sample_id", "origin"]].copy()
    for column, unit in (
        ("parking_altitude_km", "km"),
        ("preparation_altitude_km", "km"),
        ("separation_delay_h", "h"),
    ):
        shown[f"{column.removesuffix('_' + unit)} [{unit}]"] = front[column]
    for o in normalisation.objectives:
        shown[f"{o.label} [{o.report_unit}]"] = front[o.name] * o.report_scale
    return shown


def _rounds_frame(summary: dict[str, Any]) -> pd.DataFrame:
    rows = [
        {
            "round": i["iteration"],
            "training samples": i["samples"],
            "feasible": i["feasible"],
            "surrogate front points": i["surrogate_front_points"],
            "surrogate hypervolume": i["surrogate_hypervolume"],
            "verified points": i.get("verified_points"),
            "largest error": (f"{i['max_error']:.1%}" if "max_error" in i else None),
            "infill run": i.get("infill_run"),
        }
        for i in summary.get("iterations", [])
    ]
    return pd.DataFrame(rows)


def _totals_rows(plan: Any) -> list[tuple[str, str]]:
    """The plan's totals beside the front's values of the same design: the plan flies from
    the launch solved at its altitude, the front's evaluation from the launch fit, so
    they differ a little (and more where a stage's solver found another local optimum)."""
    front = plan.source.get("front_objectives", {})
    rows = []
    for label, name, scale, unit in (
        ("T_total", "t_total_s", 1 / S_PER_HOUR, "h"),
        ("dV_total", "dv_total_mps", 1.0, "m/s"),
        ("M_load", "m_load_kg", 1.0, "kg"),
    ):
        value = getattr(plan.totals, name) * scale
        text = f"{number(value, digits=4)} {unit}"
        if name in front:
            stored = front[name] * scale
            text += (
                f" (front: {number(stored, digits=4)} {unit}, "
                f"difference {number(value - stored, digits=3)} {unit})"
            )
        rows.append((label, text))
    return rows


def _plan_rows(plan: Any) -> pd.DataFrame:
    rows = [
        ("launch day", utc(plan.launch_day_utc)),
        ("drop", utc(plan.launch.drop_epoch_utc)),
        ("payload in orbit", f"{number(plan.launch.payload_kg, digits=4)} kg"),
        ("rendezvous wait", f"{number(plan.rendezvous.wait_time_s / S_PER_HOUR, digits=4)} h"),
        ("docking", utc(plan.stay.docking_epoch_utc)),
        ("separation", utc(plan.stay.separation_epoch_utc)),
        (
            "deorbit burn",
            f"{utc(plan.deorbit.burn.epoch_utc)}, {number(plan.deorbit.burn.dv_mps, digits=4)} m/s",
        ),
        ("entry interface", utc(plan.deorbit.entry_epoch_utc)),
        (
            "landing",
            f"{utc(plan.terminal.epoch_utc)} at {plan.terminal.landing_site_name}, "
            f"miss {number(plan.terminal.miss_distance_m / M_PER_KM, digits=3)} km",
        ),
        *_totals_rows(plan),
        ("peak heat rate", f"{number(plan.reentry.max_heat_rate_w_m2 / 1000.0, digits=4)} kW/m²"),
        ("peak load factor", f"{number(plan.reentry.max_load_g, digits=3)} g"),
        (
            "peak dynamic pressure",
            f"{number(plan.reentry.max_dynamic_pressure_pa / 1000.0, digits=4)} kPa",
        ),
    ]
    return pd.DataFrame(rows, columns=["quantity", "value"])


_VALIDATION_COLUMNS = (
    "model",
    "kind",
    "candidate",
    "n_train",
    "n_heldout",
    "cv_rmse",
    "cv_q2",
    "heldout_rmse",
    "heldout_r2",
    "cv_accuracy",
    "heldout_accuracy",
)

# The look of the HTML pages (this report and the launch window's page).
STYLE = """
body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1100px;color:#222}
h1{font-size:1.5em}h2{font-size:1.15em;margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;font-size:.85em;margin:.5em 0}
td,th{border:1px solid #ccc;padding:.2em .5em;text-align:right}th{background:#f3f3f3}
.verdict{padding:.6em 1em;border-left:.4em solid}.ok{border-color:#2a2;background:#efe}
.no{border-color:#d80;background:#fff6e6}figure{margin:1em 0}img{max-width:100%}
figcaption{font-size:.8em;color:#555}
"""


def _since_previous_section(since: tuple[Any, list[Any]] | None) -> list[str]:
    """ "Since the previous plan of this target": the figures that changed, both values, the
    change and the unit (inputs first)."""
    if since is None:
        return []
    from ovtraj.tracking.diff import text_rows

    row, found = since
    head = (
        "<h2>Since the previous plan of this target</h2>"
        f"<p>previous plan {html.escape(str(row['plan_id']))} (pipeline "
        f"{html.escape(str(row['pipeline_id']))}, element set of "
        f"{html.escape(utc(row['element_set_epoch_utc']))}, code "
        f"{html.escape(str(row['code_version']))}): {len(found)} figures changed.</p>"
    )
    if not found:
        return [head]
    frame = pd.DataFrame(
        text_rows(found), columns=["group", "field", "previous", "this plan", "change"]
    )
    return [head, _table(frame)]


def _figure(path: Path, alt: str, caption: str) -> str:
    """A PNG embedded as a figure: ``alt`` names what it shows, the caption adds its file."""
    return (
        f"<figure><img alt='{html.escape(alt)}' src='{png_data_uri(path)}'>"
        f"<figcaption>{html.escape(caption)} ({html.escape(path.name)})</figcaption></figure>"
    )


# The bounds of the report's section of the plan's flights (:func:`flown_section`).
FLOWN_START = "<section id='flown'>"
FLOWN_END = "</section>"

# Alt text of the plan's own figures (the test of the rendered report finds them by it).
ASCENT_ALT = "ascent profile from the drop"
ENTRY_ALT = "entry time histories against their limits"


def _plan_sections(
    plan: Any, ascent_plot: Path | None, entry_plot: Path | None, flights: Sequence[Any]
) -> list[str]:
    """Path peaks against their limits, the manoeuvres, the ascent, the entry's time
    histories and the flights of the plan (or where to get one)."""
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    manoeuvres, note = manoeuvres_shown(plan, scenario)
    parts = [
        "<h2>Path peaks against their limits</h2>",
        "<p>Each peak of the plan against the limit its scenario sets (margin = limit - "
        "peak, in the limit's unit and as a percentage of it; negative: over the limit).</p>",
        _table(margins_shown(plan, scenario)),
        "<h2>Manoeuvres</h2>",
        f"<p>{html.escape(note)}.</p>",
        _table(manoeuvres),
        "<h2>Ascent from the drop</h2>",
    ]
    if ascent_plot is None:
        parts.append("<p>no ascent profile: the plan's programme was not flown again.</p>")
    else:
        parts.append(
            _figure(
                ascent_plot,
                ASCENT_ALT,
                "Altitude, speed, flight-path angle, dynamic pressure, axial load and mass "
                "against time from the drop: the plan's programme flown by the launch stage's "
                "model, the launcher's limits dashed",
            )
        )
    parts.append("<h2>Entry time histories</h2>")
    if entry_plot is None:
        parts.append("<p>no entry time histories: the reentry's trajectory is not given.</p>")
    else:
        parts.append(
            _figure(
                entry_plot,
                ENTRY_ALT,
                "Heat rate, load factor, dynamic pressure and bank angle against time from the "
                "entry interface (the reentry stage's trajectory table), each limit dashed",
            )
        )
    parts.append(flown_section(flights, plan))
    return parts


def flown_section(flights: Sequence[Any], plan: Any) -> str:
    """The report's section of the plan's flights (each as ``ovtraj fly PLAN --json`` prints
    it, in the order given), or where to get one; between :data:`FLOWN_START` and
    :data:`FLOWN_END`, so that the section alone can be written again when a flight is
    stored (:mod:`ovtraj.pipeline.plan_flights`). Refuses another plan's flight
    (:class:`~ovtraj.pipeline.report_tables.FlightResultError`)."""
    parts = [FLOWN_START, "<h2>Flown</h2>"]
    if not flights:
        parts.append(
            "<p>No flight of this plan is stored: <code>ovtraj fly PLAN</code> (J2 replay) and "
            "<code>ovtraj fly PLAN --fidelity high</code> store theirs beside a plan of a run "
            "store (<code>&lt;plan&gt;-flight-j2.json</code>, "
            "<code>&lt;plan&gt;-flight-high.json</code>) and show them here.</p>"
        )
    for flight in flights:
        sentence, frame = flight_shown(flight, plan)
        parts += [f"<p>{html.escape(sentence)}.</p>", _table(frame)]
    parts.append(FLOWN_END)
    return "\n".join(parts)


def write_report(
    path: Path,
    *,
    scenario_name: str,
    normalisation: Normalisation,
    summary: dict[str, Any],
    verify: Any,
    front: pd.DataFrame,
    plan: Any,
    pick_text: str,
    surrogates: Any,
    plots: list[Path],
    since_previous: tuple[Any, list[Any]] | None = None,
    ascent_plot: Path | None = None,
    entry_plot: Path | None = None,
    flights: Sequence[Any] = (),
) -> Path:
    """The HTML report of a planned pipeline result at ``path`` (rewritten with the plan:
    it is a view of stored results); returns ``path``. ``since_previous``: the previous
    plan of this target (its history row) and the changes since
    (:mod:`ovtraj.tracking.diff`), a section of their own. ``ascent_plot`` and
    ``entry_plot``: the PNGs of the plan's ascent (:mod:`ovtraj.plots.ascent`) and entry
    time histories (:mod:`ovtraj.plots.entry`), each in its own section. ``flights``: the
    flights of this plan as ``ovtraj fly PLAN --json`` prints them (the J2 replay, the
    ``--fidelity high`` result: those stored beside the plan,
    :func:`ovtraj.pipeline.plan_flights.stored_flights`), each shown beside the plan; a
    mapping of neither kind, or the flight of another plan, raises
    :class:`~ovtraj.pipeline.report_tables.FlightResultError` before anything is written."""
    plan_parts = _plan_sections(plan, ascent_plot, entry_plot, flights)
    title = f"ovtraj mission report: {scenario_name}"
    parts = [
        f"<!doctype html><html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        *_verdict_section(summary, verify, front),
        "<h2>The plan</h2>",
        f"<p>{html.escape(pick_text)}.</p>",
        _table(_plan_rows(plan)),
        *plan_parts,
        *_since_previous_section(since_previous),
        "<h2>Verification rounds</h2>",
        _table(_rounds_frame(summary)),
        "<h2>Verified front (real chain)</h2>",
        "<p>T_total and dV_total: lower is better; M_load: higher is better.</p>",
        _table(_front_frame(front, normalisation)),
        "<h2>Surrogates of the last round (selected models)</h2>",
        *_surrogates_section(surrogates),
        "<h2>Plots</h2>",
    ]
    for plot in plots:
        parts.append(
            f"<figure><img alt='{html.escape(plot.name)}' src='{png_data_uri(plot)}'>"
            f"<figcaption>{html.escape(plot.name)}</figcaption></figure>"
        )
    parts.append("</body></html>\n")
    write_bytes(path, "\n".join(parts).encode("utf-8"), replace=True)
    return path


def _verdict_section(summary: dict[str, Any], verify: Any, front: pd.DataFrame) -> list[str]:
    """Which pipeline and code, whether the loop converged and why it stopped, the real
    evaluations and the verified front's size and hypervolume."""
    converged = bool(summary.get("converged"))
    evaluations = summary["real_evaluations"]
    return [
        f"<p>pipeline {html.escape(summary['pipeline_id'])} of DoE run "
        f"{html.escape(summary['doe_run'])} (final run {html.escape(summary['final_run'])}), "
        f"code {html.escape(str(summary.get('code')))}</p>",
        f"<p class='verdict {'ok' if converged else 'no'}'>"
        f"{html.escape(stop_explanation(summary, verify))}.</p>",
        f"<p>real evaluations: {evaluations['doe']} (DoE) + {evaluations['infill']} (infill); "
        f"verified front: {len(front)} points, hypervolume {summary['hypervolume']:.4f} "
        "(normalised objectives, reference point 1).</p>",
    ]


def _surrogates_section(surrogates: Any) -> list[str]:
    """The selected models' validation figures, and the outputs modelled without a
    regressor; or that the last round's fit is no longer stored."""
    if surrogates is None:
        return ["<p>the last round's surrogate fit is no longer stored.</p>"]
    validation = surrogates.validation
    chosen = validation[validation["selected"].astype(bool)]
    shown = [c for c in _VALIDATION_COLUMNS if c in chosen and chosen[c].notna().any()]
    parts = [
        "<p>k-fold cross-validation (cv_) and held-out (heldout_) figures of each output's "
        "selected model, in the output's unit (times in s).</p>",
        _table(chosen[shown]),
    ]
    for output, model in unregressed(surrogates).items():
        why = _UNREGRESSED.get(model, "")
        parts.append(
            f"<p>{html.escape(output)}: {html.escape(model)}, not a regressor{why}: "
            "no cross-validation figures.</p>"
        )
    return parts
