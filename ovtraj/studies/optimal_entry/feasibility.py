"""Feasibility check of an optimised entry (seed 001, sec. 3.3).

The optimal controls, known at the (unequally spaced) collocation points, are
interpolated in time, linearly or by a cubic spline (seed: "linear or cubic spline"),
and flown from the initial state to the optimised final time by the independent numpy
model and integrator of :mod:`ovtraj.studies.optimal_entry.flight`. The difference
between the integrated and the optimised terminal states measures how far the discrete
optimum is from a trajectory the vehicle can fly.

Controls are held at their first and last collocation values outside the collocation
points (LG has none at the ends), and a spline is clipped to the control bounds. The
position error is the straight-line distance between the two terminal points
(``r = R + h`` on the spherical Earth); the angle error is the largest of the
flight-path angle, heading, latitude and longitude differences.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from ovtraj.deadline import Deadline
from ovtraj.studies.optimal_entry.flight import fly
from ovtraj.studies.optimal_entry.flight_kernel import ControlTable
from ovtraj.studies.optimal_entry.problem import EntryProblem

__all__ = ["FeasibilityReport", "check_feasibility", "control_table", "position_distance_m"]


@dataclass(frozen=True)
class FeasibilityReport:
    """Integrated minus optimised terminal state, and the integrated path's maxima."""

    interpolation: str
    status: str
    position_error_km: float
    altitude_error_km: float
    speed_error_mps: float
    fpa_error_deg: float
    heading_error_deg: float
    latitude_error_deg: float
    longitude_error_deg: float
    max_load_g: float
    max_dynamic_pressure_kpa: float
    max_heat_rate_kw_m2: float
    t: NDArray[np.float64]  # integrated times [s]
    y: NDArray[np.float64]  # rows of (h, lon, lat, V, gamma, psi), SI

    @property
    def angle_error_deg(self) -> float:
        return max(
            abs(self.fpa_error_deg),
            abs(self.heading_error_deg),
            abs(self.latitude_error_deg),
            abs(self.longitude_error_deg),
        )


def _pieces(t: NDArray[np.float64], values: NDArray[np.float64], kind: str) -> tuple:
    """Breakpoints and piecewise-polynomial coefficients (scipy's ``PPoly`` layout)."""
    if kind == "linear":
        slopes = np.diff(values) / np.diff(t)
        return t, np.vstack([slopes, values[:-1]])
    if kind == "cubic":
        spline = CubicSpline(t, values)  # not-a-knot
        return spline.x, spline.c
    raise ValueError(f"unknown interpolation {kind!r} (use 'linear' or 'cubic')")


def control_table(
    t: NDArray[np.float64],
    alpha: NDArray[np.float64],
    bank: NDArray[np.float64],
    kind: str,
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
) -> ControlTable:
    """Controls through ``(t, alpha)`` and ``(t, bank)`` [rad]: linear or not-a-knot cubic
    spline, held at the ends, clipped to ``[lower, upper]`` (alpha, bank)."""
    t = np.asarray(t, dtype=float)
    alpha_x, alpha_c = _pieces(t, np.asarray(alpha, dtype=float), kind)
    bank_x, bank_c = _pieces(t, np.asarray(bank, dtype=float), kind)
    return ControlTable(
        np.ascontiguousarray(alpha_x),
        np.ascontiguousarray(alpha_c),
        np.ascontiguousarray(bank_x),
        np.ascontiguousarray(bank_c),
        np.asarray(lower, dtype=float),
        np.asarray(upper, dtype=float),
    )


def position_distance_m(a: NDArray[np.float64], b: NDArray[np.float64], radius: float) -> float:
    """Straight-line distance [m] between two ``(h, lon, lat, ...)`` states over a sphere."""

    def cartesian(state: NDArray[np.float64]) -> NDArray[np.float64]:
        r, lon, lat = radius + state[0], state[1], state[2]
        return r * np.array(
            [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)]
        )

    return float(np.linalg.norm(cartesian(a) - cartesian(b)))


def check_feasibility(
    problem: EntryProblem,
    t_controls: NDArray[np.float64],
    alpha: NDArray[np.float64],
    bank: NDArray[np.float64],
    final_time: float,
    final_state: NDArray[np.float64],
    interpolation: str,
    deadline: Deadline | None = None,
) -> FeasibilityReport:
    """Fly the controls ``alpha(t)``, ``bank(t)`` [rad] to ``final_time`` [s] and compare.

    ``final_state`` is the optimised terminal ``(h, lon, lat, V, gamma, psi)`` (SI).
    """
    settings = problem.config.feasibility
    controls = control_table(
        t_controls, alpha, bank, interpolation, problem.control_lower, problem.control_upper
    )
    flown = fly(
        problem,
        controls,
        final_time,
        rtol=settings.relative_tolerance,
        atol=settings.absolute_tolerance,
        breaks=np.asarray(t_controls) if interpolation == "linear" else None,
        deadline=deadline,
    )
    end = flown.y[-1]
    heat, load, dynamic_pressure = flown.path.T
    deg = math.degrees
    position = position_distance_m(end, final_state, problem.radius)
    if flown.status != "completed":
        position = math.inf
    return FeasibilityReport(
        interpolation=interpolation,
        status=flown.status,
        position_error_km=position / 1e3,
        altitude_error_km=float(end[0] - final_state[0]) / 1e3,
        speed_error_mps=float(end[3] - final_state[3]),
        fpa_error_deg=deg(end[4] - final_state[4]),
        heading_error_deg=deg(end[5] - final_state[5]),
        latitude_error_deg=deg(end[2] - final_state[2]),
        longitude_error_deg=deg(end[1] - final_state[1]),
        max_load_g=float(np.max(np.abs(load))),
        max_dynamic_pressure_kpa=float(np.max(dynamic_pressure)) / 1e3,
        max_heat_rate_kw_m2=float(np.max(heat)) / 1e3,
        t=flown.t,
        y=flown.y,
    )
