"""The plan report's tables of the plan itself, as text ready to show (:mod:`.report`).

* :func:`margins_shown`: every path peak against its limit (:mod:`ovtraj.mission.margins`);
* :func:`manoeuvres_shown`: every burn, its RTN components, duration and propellant
  (:mod:`ovtraj.mission.manoeuvres`), with the sentence that says how they are computed;
* :func:`flight_shown`: a flight of the plan beside the plan, from the result
  ``ovtraj fly PLAN --json`` prints (the J2 replay's
  :class:`~ovtraj.mission.flight_report.FlightReport` or ``--fidelity high``'s
  :func:`~ovtraj.mission.sky_flight.fidelity_report`).

A flight result is data from outside (a file the user saved): each figure is read only when
it is a finite number, text is shown as text (the report escapes it), and a result of
neither kind is refused naming what it lacks.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import pandas as pd

from ovtraj.config import Scenario
from ovtraj.formatting import MISSING, clipped, number, printable, utc
from ovtraj.mission.manoeuvres import manoeuvre_table, propellant_budget
from ovtraj.mission.margins import limit_margins
from ovtraj.mission.montecarlo_outcome import MANOEUVRES
from ovtraj.mission.montecarlo_statistics import path_limits, planned_dv
from ovtraj.mission.plan import MissionPlan
from ovtraj.units import S_PER_HOUR

__all__ = ["FlightResultError", "flight_shown", "manoeuvres_shown", "margins_shown"]

# The path-limit margins of a --fidelity high result (limit - peak, SI): key, label, unit
# shown, scale to it.
_PATH_MARGINS = (
    ("max_heat_rate_w_m2", "entry heat-rate margin", "kW/m²", 1e-3),
    ("max_load_g", "entry load-factor margin", "g", 1.0),
    ("max_dynamic_pressure_pa", "entry dynamic-pressure margin", "kPa", 1e-3),
)
_TEXT_CHARS = 200  # of a text of the flight result shown (a reason, a file name)


def margins_shown(plan: MissionPlan, scenario: Scenario) -> pd.DataFrame:
    """quantity, peak, limit, margin (limit - peak), margin [%] of the limit, unit, whether
    the peak is within, and the limit's config key."""
    rows = []
    for m in limit_margins(plan, scenario):
        if not m.within:
            status = "EXCEEDED"
        elif m.peak > m.limit:
            status = f"within (up to {m.allowance_fraction:.1%} over counts as within)"
        else:
            status = "within"
        rows.append(
            {
                "quantity": m.quantity,
                "peak": number(m.peak, digits=5),
                "limit": number(m.limit, digits=5),
                "margin": number(m.margin, digits=4),
                "margin [%]": f"{m.margin_percent:.1f}",
                "unit": m.unit,
                "status": status,
                "limit from": m.source,
            }
        )
    return pd.DataFrame(rows)


def manoeuvres_shown(plan: MissionPlan, scenario: Scenario) -> tuple[pd.DataFrame, str]:
    """The burns of the plan as text, and a sentence on what the table holds and how the
    durations and propellant masses are computed (with the propellant budget)."""
    table = manoeuvre_table(plan, scenario)
    vehicle = scenario.vehicle
    shown = pd.DataFrame(
        {
            "manoeuvre": table["name"],
            "epoch (UTC)": [utc(epoch) for epoch in table["epoch_utc"]],
            "dV radial R [m/s]": [number(v, decimals=3) for v in table["dv_radial_mps"]],
            "dV along-track T [m/s]": [number(v, decimals=3) for v in table["dv_along_track_mps"]],
            "dV cross-track N [m/s]": [number(v, decimals=3) for v in table["dv_cross_track_mps"]],
            "|dV| [m/s]": [number(v, decimals=3) for v in table["dv_mps"]],
            "mass before [kg]": [number(v, decimals=3) for v in table["mass_before_kg"]],
            "duration [s]": [number(v, decimals=2) for v in table["duration_s"]],
            "propellant [kg]": [number(v, decimals=3) for v in table["propellant_kg"]],
        }
    )
    budget = propellant_budget(table, scenario)
    g0 = scenario.earth.g0_m_s2
    note = (
        f"Every impulse of the plan in time order; the launcher inserts the OV into its "
        f"parking orbit at {utc(plan.launch.insertion_epoch_utc)} (no OV burn), and the plan "
        "holds no mid-course correction (only the closed-loop flights of ovtraj fly "
        "--fidelity high make them). RTN: radial, along-track and cross-track components "
        "at the burn state, as the plan stores them. The OV flies each burn as an impulse; "
        f"the duration is the finite burn of its engine at vehicle.thrust_n "
        f"{number(vehicle.thrust_n, 'N')} and the propellant the rocket equation's, with "
        f"vehicle.isp_s {number(vehicle.isp_s, 's')} and earth.g0_m_s2 "
        f"{number(g0, 'm/s²', digits=6)}, each burn from the mass the earlier ones left, "
        f"from the wet mass in orbit vehicle.mass_kg {number(vehicle.mass_kg, 'kg')}. "
        f"Propellant: {number(budget.used_kg, 'kg')} of the "
        f"{number(budget.loaded_kg, 'kg')} loaded (vehicle.mass_kg - vehicle.dry_mass_kg), "
        f"margin {number(budget.margin_kg, 'kg')}"
    )
    return shown, note


class FlightResultError(ValueError):
    """A flight result that is neither kind ``ovtraj fly --json`` prints, or the flight of
    another plan."""


def _figure(data: Any, *keys: str) -> float | None:
    """``data[keys[0]][keys[1]]...`` when it is a finite number, else None."""
    for key in keys:
        if not isinstance(data, Mapping):
            return None
        data = data.get(key)
    if isinstance(data, bool) or not isinstance(data, int | float):
        return None
    try:
        value = float(data)
    except OverflowError:  # an integer beyond any float
        return None
    return value if math.isfinite(value) else None


def _text(value: float | None, scale: float = 1.0, digits: int = 6) -> str:
    return MISSING if value is None else number(value * scale, digits=digits)


def _difference(flown: float | None, planned: float | None, scale: float = 1.0) -> str:
    if flown is None or planned is None:
        return MISSING
    return number((flown - planned) * scale, digits=3)


def flight_shown(flight: Mapping[str, Any], plan: MissionPlan) -> tuple[str, pd.DataFrame]:
    """A sentence naming the flight and its verdict, and its figures beside the plan's.
    Raises :class:`FlightResultError` for a mapping of neither kind or another plan's."""
    if not isinstance(flight, Mapping):
        raise FlightResultError(f"flight: expected a mapping, got {type(flight).__name__}")
    if flight.get("fidelity") == "high":
        _same_plan(_figure(flight, "plan", "predicted_landing_miss_m"), plan)
        return _high_fidelity(flight, plan)
    if "checks" in flight and "landed_within_stated_miss" in flight:
        _same_plan(_figure(flight, "predicted_miss_distance_m"), plan)
        return _replay(flight, plan)
    raise FlightResultError(
        "flight: neither the replay of `ovtraj fly PLAN --json` (no checks and "
        "landed_within_stated_miss) nor its --fidelity high result (fidelity is not 'high')"
    )


def _same_plan(predicted_miss_m: float | None, plan: MissionPlan) -> None:
    """Refuse the flight of another plan: every flight result carries the plan's predicted
    landing miss, which differs from plan to plan (no plan id is in it)."""
    if predicted_miss_m is None or not math.isclose(
        predicted_miss_m, plan.terminal.miss_distance_m, rel_tol=1e-12, abs_tol=1e-9
    ):
        raise FlightResultError(
            f"flight: not a flight of this plan: its plan's predicted landing miss "
            f"{_text(predicted_miss_m)} m is not this plan's "
            f"{number(plan.terminal.miss_distance_m, digits=12)} m"
        )


def _shown(value: Any) -> str:
    """A text of the flight result on one line, cut at ``_TEXT_CHARS``; ``-`` for no text."""
    if not isinstance(value, str) or not value:
        return MISSING
    return clipped(printable(value), _TEXT_CHARS)


def _verdict(landed: Any) -> str:
    return "landed within the stated miss" if landed is True else "NOT within the stated miss"


def _replay(flight: Mapping[str, Any], plan: MissionPlan) -> tuple[str, pd.DataFrame]:
    """The J2 replay from the drop (open loop) beside the plan."""
    burns = flight.get("burns")
    dv_total = None
    if isinstance(burns, list) and len(burns) == len(plan.impulses()):  # every burn flown
        dv = [_figure(burn, "dv_mps") for burn in burns]
        dv_total = None if None in dv else sum(dv)
    terminal_t = _figure(flight, "terminal", "t_s")
    t_total = None if terminal_t is None else terminal_t - plan.launch.drop_t_s
    checks = flight.get("checks") if isinstance(flight.get("checks"), Mapping) else {}
    rows = [
        ("T_total", "h", plan.totals.t_total_s, t_total, 1 / S_PER_HOUR),
        ("dV_total", "m/s", plan.totals.dv_total_mps, dv_total, 1.0),
        ("M_load", "kg", plan.totals.m_load_kg, _figure(flight, "insertion", "payload_kg"), 1.0),
        (
            "landing miss",
            "km",
            plan.terminal.miss_distance_m,
            _figure(flight, "miss_distance_m"),
            1e-3,
        ),
        (
            "rendezvous arrival miss",
            "m",
            plan.rendezvous.arrival_miss_m,
            _figure(flight, "rendezvous_arrival_miss_m"),
            1.0,
        ),
        (
            "entry peak heat rate",
            "kW/m²",
            plan.reentry.max_heat_rate_w_m2,
            _figure(checks, "max_heat_rate_w_m2", "value"),
            1e-3,
        ),
        (
            "entry peak load factor",
            "g",
            plan.reentry.max_load_g,
            _figure(checks, "max_load_g", "value"),
            1.0,
        ),
        (
            "entry peak dynamic pressure",
            "kPa",
            plan.reentry.max_dynamic_pressure_pa,
            _figure(checks, "max_dynamic_pressure_pa", "value"),
            1e-3,
        ),
    ]
    frame = pd.DataFrame(
        [
            {
                "quantity": label,
                "plan": _text(planned, scale),
                "flown (J2 replay)": _text(flown, scale),
                "flown - plan": _difference(flown, planned, scale),
                "unit": unit,
            }
            for label, unit, planned, flown, scale in rows
        ]
    )
    completed = "completed" if flight.get("ok") is True else "FAILED"
    reason = _shown(flight.get("reason"))
    sentence = (
        f"The plan replayed open-loop from the drop under the J2 model (ovtraj fly PLAN): "
        f"{completed}, {_verdict(flight.get('landed_within_stated_miss'))}"
        + ("" if reason == MISSING else f"; reason: {reason}")
    )
    return sentence, frame


def _high_fidelity(flight: Mapping[str, Any], plan: MissionPlan) -> tuple[str, pd.DataFrame]:
    """The nominal closed loops under the J2 and the high-fidelity skies beside the plan."""
    flights = ("closed_loop_j2", "closed_loop_high_fidelity")
    planned = planned_dv(plan)
    rows: list[tuple[str, str, float | None, tuple[str, ...], float]] = [
        (f"{name} dV", "m/s", planned[name], ("dv_mps", name), 1.0) for name in MANOEUVRES
    ]
    rows += [
        ("dV_total", "m/s", planned["total"], ("dv_total_mps",), 1.0),
        ("rendezvous arrival miss", "m", plan.rendezvous.arrival_miss_m, ("arrival_miss_m",), 1.0),
        ("landing miss", "km", plan.terminal.miss_distance_m, ("landing_miss_m",), 1e-3),
    ]
    limits = path_limits(plan)
    rows += [  # the plan's margin: the limit minus the plan's own peak (same names)
        (
            label,
            unit,
            limits[name] - getattr(plan.reentry, name),
            ("path_limit_margins", name),
            scale,
        )
        for name, label, unit, scale in _PATH_MARGINS
    ]
    shown = [
        {
            "quantity": label,
            "plan": _text(value, scale),
            "closed loop, J2": _text(_figure(flight, flights[0], *keys), scale),
            "closed loop, high fidelity": _text(_figure(flight, flights[1], *keys), scale),
            "unit": unit,
        }
        for label, unit, value, keys, scale in rows
    ]
    extra = _figure(flight, "extra_dv_mps")
    sentence = (
        "The plan flown closed-loop without dispersions under the J2 and the high-fidelity "
        "skies (ovtraj fly PLAN --fidelity high, force model "
        f"{_shown(flight.get('force_model_file'))}): "
        f"{_verdict(flight.get('landed_within_stated_miss'))}; extra dV under the "
        f"high-fidelity sky {MISSING if extra is None else number(extra, 'm/s', decimals=2)}"
    )
    return sentence, pd.DataFrame(shown)
