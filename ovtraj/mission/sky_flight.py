"""The plan flown closed-loop without dispersions, under the J2 sky and under the
high-fidelity one, side by side with the plan (``ovtraj fly PLAN --fidelity high``).

The closed loop is the Monte Carlo's (:func:`ovtraj.mission.montecarlo_flight.fly_closed_loop`)
with every error drawn as zero: the corrections then answer only what the sky does
differently from the planner's model. Under the J2 sky that is nothing (the figures equal
the plan's to the solvers' tolerances); under the high-fidelity sky (EGM2008, drag, Sun,
Moon, radiation pressure) it is the dV the J2 plan hides: the phasing re-targeted while
it drifts, the mid-course corrections, the transfer and deorbit solved again, the
entry guided to the site.
"""

from __future__ import annotations

from typing import Any

from ovtraj.config import Scenario, scenario_from_dict
from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.config.force_model import ForceModelSettings
from ovtraj.formatting import number, printable, split_unit
from ovtraj.mission.montecarlo_draw import draw_run
from ovtraj.mission.montecarlo_flight import fly_closed_loop
from ovtraj.mission.montecarlo_outcome import MANOEUVRES, PATH_LIMITS, RunOutcome
from ovtraj.mission.montecarlo_statistics import path_limits, planned_dv
from ovtraj.mission.plan import MissionPlan

__all__ = ["fidelity_report", "fly_nominal", "format_fidelity_report", "nominal_dispersions"]


def nominal_dispersions(config: DispersionsConfig) -> DispersionsConfig:
    """``config`` with every 1-sigma error zero (the corrections' settings kept)."""

    def zero(group: Any, *keep: str) -> Any:
        return group.model_copy(
            update={
                name: 0.0
                for name, value in group.model_dump().items()
                if isinstance(value, float) and name not in keep
            }
        )

    return config.model_copy(
        update={
            "drop": zero(config.drop),
            "stages": zero(config.stages),
            "navigation": zero(config.navigation),
            "burns": zero(config.burns),
            "entry": zero(config.entry, "minimum_factor"),
            "closed_loop": config.closed_loop.model_copy(update={"accelerometer_fraction": 0.0}),
        }
    )


def fly_nominal(
    plan: MissionPlan,
    config: DispersionsConfig,
    force_model: ForceModelSettings | None = None,
    scenario: Scenario | None = None,
) -> RunOutcome:
    """The plan flown closed-loop with no error, under ``force_model`` (None: the J2 sky)."""
    nominal = nominal_dispersions(config)
    scenario = scenario or scenario_from_dict(plan.scenario, "the plan's scenario")
    draw = draw_run(nominal, 0, 0, len(plan.impulses()))
    return fly_closed_loop(plan, draw, nominal, scenario, force_model)


def _flight(outcome: RunOutcome, limits: dict[str, float]) -> dict[str, Any]:
    return {
        "landed": outcome.landed,
        "failed_stage": outcome.failed_stage,
        "reason": outcome.reason,
        "dv_mps": {name: outcome.dv_mps.get(name) for name in MANOEUVRES},
        "dv_total_mps": outcome.dv_total_mps,
        "arrival_miss_m": outcome.arrival_miss_m,
        "landing_miss_m": outcome.landing_miss_m,
        "path_limit_margins": {
            name: (limits[name] - outcome.maxima[name]) if name in outcome.maxima else None
            for name in PATH_LIMITS
        },
    }


def fidelity_report(
    plan: MissionPlan,
    j2: RunOutcome,
    high: RunOutcome,
    settings: ForceModelSettings,
    source: str = "configs/force_model.yaml",
) -> dict[str, Any]:
    """The plan's dV beside the nominal closed-loop flights under both skies: each
    manoeuvre, the total, the high-fidelity flight's extra dV, the arrival and landing
    misses, the path-limit margins and whether it landed within the stated miss.
    ``source`` is the force-model file ``settings`` were read from, which the report
    names (the shipped one, or the user's ``--force-model``)."""
    limits, planned = path_limits(plan), planned_dv(plan)
    stated = plan.terminal.stated_miss_m
    high_flight = _flight(high, limits)
    extra = None
    if high.dv_total_mps is not None:
        extra = high.dv_total_mps - planned["total"]
    within = bool(high.landed and high.landing_miss_m is not None and high.landing_miss_m <= stated)
    return {
        "fidelity": "high",
        "force_model": settings.model_dump(mode="json"),
        "force_model_file": source,
        "plan": {
            "dv_mps": {name: planned[name] for name in MANOEUVRES},
            "dv_total_mps": planned["total"],
            "predicted_landing_miss_m": plan.terminal.miss_distance_m,
            "stated_miss_m": stated,
        },
        "closed_loop_j2": _flight(j2, limits),
        "closed_loop_high_fidelity": high_flight,
        "extra_dv_mps": extra,
        "landed_within_stated_miss": within,
    }


def format_fidelity_report(report: dict[str, Any]) -> str:
    """The report as a table: a row per figure, a column per flight."""
    plan, j2 = report["plan"], report["closed_loop_j2"]
    high = report["closed_loop_high_fidelity"]

    def mps(value: float | None) -> str:
        return "-" if value is None else f"{value:.2f}"

    def km(value: float | None) -> str:
        return "-" if value is None else number(value / 1e3, "", decimals=3)

    rows = [("", "plan (J2)", "closed loop, J2", "closed loop, high fidelity")]
    for name in MANOEUVRES:
        rows.append(
            (
                f"{name} [m/s]",
                mps(plan["dv_mps"][name]),
                mps(j2["dv_mps"][name]),
                mps(high["dv_mps"][name]),
            )
        )
    rows.append(
        (
            "dV total [m/s]",
            mps(plan["dv_total_mps"]),
            mps(j2["dv_total_mps"]),
            mps(high["dv_total_mps"]),
        )
    )
    rows.append(("arrival miss [m]", "-", mps(j2["arrival_miss_m"]), mps(high["arrival_miss_m"])))
    rows.append(
        (
            "landing miss [km]",
            km(plan["predicted_landing_miss_m"]),
            km(j2["landing_miss_m"]),
            km(high["landing_miss_m"]),
        )
    )
    for name in PATH_LIMITS:
        stem, unit = split_unit(name)
        rows.append(
            (
                f"{stem.replace('_', ' ')} margin [{unit}]",
                "-",
                _margin(j2["path_limit_margins"][name]),
                _margin(high["path_limit_margins"][name]),
            )
        )
    widths = [max(len(row[k]) for row in rows) for k in range(4)]
    source = printable(report.get("force_model_file", "configs/force_model.yaml"))
    lines = [f"flown closed loop, no dispersion (force model: {source})"]
    for row in rows:
        lines.append(
            "  "
            + row[0].ljust(widths[0])
            + "  "
            + "  ".join(cell.rjust(widths[k + 1]) for k, cell in enumerate(row[1:]))
        )
    for label, flight in (("J2", j2), ("high fidelity", high)):
        if not flight["landed"]:
            lines.append(f"  {label}: failed in {flight['failed_stage']}: {flight['reason']}")
    extra = report["extra_dv_mps"]
    lines.append(
        f"extra dV under the high-fidelity sky: {'-' if extra is None else f'{extra:+.2f} m/s'}; "
        f"stated miss {km(plan['stated_miss_m'])} km: "
        + ("landed within" if report["landed_within_stated_miss"] else "NOT within")
    )
    return "\n".join(lines)


def _margin(value: float | None) -> str:
    """A margin [the limit's unit], limit minus the flight's maximum."""
    return "-" if value is None else f"{value:.4g}"
