"""The manoeuvre's result: impulses, finite burns, errors; rows for tables and JSON.

Units are SI and named in the keys. ``time_of_flight_s`` and the final errors are those
of the finite-thrust solution when the correction ran, else those of the impulse plan
flown again by the propagator; the impulse plan's own figures keep an ``impulsive_``
prefix. Infeasible results keep everything the solver reached, with ``converged`` false
and ``reason`` saying why (never NaN in the rows: missing values are ``None``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from ovtraj.store.records import plain
from ovtraj.studies.maneuver.problem import ManeuverProblem

__all__ = ["BurnReport", "ManeuverResult", "comparison_rows"]


@dataclass(frozen=True)
class BurnReport:
    """One finite burn: start and duration [s], dv gained [m/s], masses [kg], direction."""

    start_s: float
    duration_s: float
    dv_mps: float  # integral of F / m: the rocket equation's c ln(m_before / m_after)
    mass_before_kg: float
    mass_after_kg: float
    direction_eci: tuple[float, float, float]

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s

    def to_dict(self) -> dict[str, Any]:
        return {
            "start_s": self.start_s,
            "duration_s": self.duration_s,
            "end_s": self.end_s,
            "dv_mps": self.dv_mps,
            "mass_before_kg": self.mass_before_kg,
            "mass_after_kg": self.mass_after_kg,
            "direction_eci": list(self.direction_eci),
            "equivalent_dv_eci_mps": [self.dv_mps * c for c in self.direction_eci],
        }


@dataclass(frozen=True)
class ManeuverResult:
    """One solve of a manoeuvre problem (see the module notes)."""

    name: str
    end_condition: str
    objective: str
    dynamics: str  # impulsive model
    finite_dynamics: str | None  # None when the finite-thrust correction did not run
    n_impulses: int
    optimizer: str
    seed: int
    converged: bool
    reason: str
    time_of_flight_s: float | None
    impulsive_time_of_flight_s: float | None
    impulse_epochs_s: list[float]
    impulse_dv_mps: list[float]
    impulse_vectors_eci_mps: list[list[float]]
    total_dv_mps: float | None
    dv_budget_mps: float  # seed eq. 14
    dv_capacity_mps: float  # rocket equation over t_e
    dv_limit_mps: float  # the cap enforced on sum |dv|
    impulse_burn_time_s: float | None  # eq. 15 durations of the impulses, summed
    max_burn_time_s: float
    constraint_violation: float  # of the best impulse plan; 0 when feasible
    constraints: dict[str, float]
    impulsive_position_error_m: float | None
    impulsive_velocity_error_mps: float | None
    burns: list[BurnReport]
    finite_total_dv_mps: float | None
    total_burn_time_s: float | None
    final_mass_kg: float | None
    final_position_error_m: float | None
    final_velocity_error_mps: float | None
    relative_speed_mps: float | None
    conversion_position_error_m: float | None  # eq. 15 burns before re-optimisation
    conversion_velocity_error_mps: float | None
    final_state_eci: list[float] | None
    goal_state_eci: list[float] | None
    generations: int
    evaluations: int
    search_time_s: float
    finite_iterations: int | None
    finite_flights: int | None
    finite_time_s: float | None
    wall_time_s: float
    history: list[tuple[int, float, float]] = field(default_factory=list, repr=False)

    def to_json(self) -> dict[str, Any]:
        """Nested, JSON-ready dict (lists of epochs, impulses and burns)."""
        out: dict[str, Any] = {}
        for name in self.__dataclass_fields__:
            if name == "history":
                continue
            value = getattr(self, name)
            if name == "burns":
                value = [b.to_dict() for b in value]
            out[name] = value
        return plain(out)

    def json(self) -> str:
        """One JSON object (what ``ovtraj maneuver --json`` prints)."""
        return json.dumps(self.to_json())

    def to_row(self) -> dict[str, Any]:
        """Flat scalars for a table or Parquet: lists spread over numbered keys."""
        row: dict[str, Any] = {}
        for key, value in self.to_json().items():
            if key == "burns":
                for k, burn in enumerate(value, start=1):
                    for name, item in burn.items():
                        if isinstance(item, list):
                            for axis, c in zip("xyz", item, strict=True):
                                row[f"burn{k}_{name}_{axis}"] = c
                        else:
                            row[f"burn{k}_{name}"] = item
            elif key == "constraints":
                for name, item in value.items():
                    row[f"constraint_{name}"] = item
            elif key == "impulse_vectors_eci_mps":
                for k, vec in enumerate(value, start=1):
                    for axis, c in zip("xyz", vec, strict=True):
                        row[f"impulse{k}_eci_{axis}_mps"] = c
            elif key in ("impulse_epochs_s", "impulse_dv_mps"):
                stem = key.removeprefix("impulse_")
                for k, item in enumerate(value, start=1):
                    row[f"impulse{k}_{stem}"] = item
            elif key in ("final_state_eci", "goal_state_eci"):
                names = ("x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps")
                for name, item in zip(names, value or [None] * 6, strict=True):
                    row[f"{key.removesuffix('_eci')}_{name}"] = item
            else:
                row[key] = value
        return row


def _fmt_list(values: list[float] | None, fmt: str) -> str:
    if values is None:
        return "-"
    return "(" + ", ".join(format(v, fmt) for v in values) + ")"


def comparison_rows(problem: ManeuverProblem, result: ManeuverResult) -> list[tuple[str, str, str]]:
    """(quantity, published, ours) as text, for the published case (config ``published``)."""
    pub = problem.config.published
    if pub is None:
        return []

    def num(value: float | None, fmt: str) -> str:
        return "-" if value is None else format(value, fmt)

    burns = result.burns
    rows = [
        (
            "time of flight [s]",
            num(pub.time_of_flight_s, ".1f"),
            num(result.time_of_flight_s, ".1f"),
        ),
        (
            "impulse epochs [s]",
            _fmt_list(pub.impulse_epochs_s, ".1f"),
            _fmt_list(result.impulse_epochs_s, ".1f"),
        ),
        (
            "impulse dv [m/s]",
            "-",
            _fmt_list(result.impulse_dv_mps, ".1f"),
        ),
        (
            "burn starts [s]",
            _fmt_list(pub.burn_starts_s, ".1f"),
            _fmt_list([b.start_s for b in burns] or None, ".1f"),
        ),
        (
            "burn durations [s]",
            _fmt_list(pub.burn_durations_s, ".1f"),
            _fmt_list([b.duration_s for b in burns] or None, ".1f"),
        ),
        (
            "burn dv [m/s]",
            _fmt_list(pub.burn_dv_mps, ".1f"),
            _fmt_list([b.dv_mps for b in burns] or None, ".1f"),
        ),
        (
            "mass before burns [kg]",
            _fmt_list(pub.mass_before_kg, ".1f"),
            _fmt_list([b.mass_before_kg for b in burns] or None, ".1f"),
        ),
        (
            "mass after burns [kg]",
            _fmt_list(pub.mass_after_kg, ".1f"),
            _fmt_list([b.mass_after_kg for b in burns] or None, ".1f"),
        ),
        (
            "total dv [m/s]",
            num(pub.total_dv_mps, ".1f"),
            f"{num(result.finite_total_dv_mps, '.1f')} finite, "
            f"{num(result.total_dv_mps, '.1f')} impulsive",
        ),
        (
            "dv budget, eq. 14 [m/s]",
            num(pub.dv_budget_mps, ".1f"),
            num(result.dv_budget_mps, ".1f"),
        ),
        (
            "final position error [m]",
            num(pub.final_position_error_m, ".3g"),
            num(result.final_position_error_m, ".3g"),
        ),
        ("final velocity error [m/s]", "-", num(result.final_velocity_error_mps, ".3g")),
    ]
    return rows
