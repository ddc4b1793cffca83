"""Bank-profile guidance: Newton on sigma_0 for range, golden section on sigma_1 for the miss.

The bank magnitude runs linearly in speed from ``sigma_0`` at entry to ``sigma_1``
at the terminal speed; the sign follows the heading-error corridor
(:mod:`.dynamics`). For a given ``sigma_1``, Newton's method (secant slope from a
finite difference) drives the signed range-to-go at the terminal speed to zero
through ``sigma_0`` (more bank, less range). Golden-section search over
``sigma_1`` then minimises ``miss + |h_f - h_T| + w * (relative path-limit
excess)``: the miss distance to the landing site, the distance of the terminal
altitude from the interface's (the terminal speed ends the flight, so the
altitude is what sigma_1 still shapes once the range is met), and a penalty for
exceeding the heat-rate, load or dynamic-pressure limits (golden section: Kiefer
1953; Press et al., *Numerical Recipes*, 3rd ed., sec. 10.2).

When no ``sigma_0`` in ``[0, sigma_max]`` nulls the range (target outside the
footprint), Newton stops at the bound that comes closest, and the solve returns
that best trajectory flagged, never raising.

Limits: Newton stops after ``newton_iterations`` (the shot says when that left the
range error above the tolerance: ``newton_exhausted``), and both searches stop at the
guidance's wall-time ``deadline``, returning the best shot so far.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ovtraj.deadline import Deadline
from ovtraj.reentry.dynamics import CRASHED, P_TARGET_LAT, P_TARGET_LON, range_and_bearing
from ovtraj.reentry.model import EntryModel, Flight

GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True)
class Limits:
    heat_rate_w_m2: float
    load_g: float
    dynamic_pressure_pa: float


@dataclass
class Shot:
    sigma0_rad: float
    sigma1_rad: float
    flight: Flight
    range_error_m: float  # signed: > 0 the site is still ahead (undershoot)
    miss_m: float
    excess: float  # largest relative path-limit excess (0 when all hold)
    newton_iterations: int = 0
    newton_exhausted: bool = False  # Newton used all its iterations, range error still above

    @property
    def cost_m(self) -> float:
        return self.miss_m if self.flight.reached else math.inf


def path_excess(flight: Flight, limits: Limits) -> float:
    return max(
        flight.max_heat_rate_w_m2 / limits.heat_rate_w_m2 - 1.0,
        flight.max_load_g / limits.load_g - 1.0,
        flight.max_dynamic_pressure_pa / limits.dynamic_pressure_pa - 1.0,
        0.0,
    )


def range_error(model: EntryModel, flight: Flight) -> tuple[float, float]:
    """(signed range-to-go, miss distance) [m] at the end of a flight."""
    p = model.params
    x = flight.state
    angle, bearing = range_and_bearing(x[2], x[1], p[P_TARGET_LAT], p[P_TARGET_LON])
    miss = angle * model.earth.radius
    ahead = math.cos(x[5] - bearing) >= 0.0
    signed = miss if ahead else -miss
    if not flight.reached:
        # A crash or a skip is scored by where it ended; a short flight undershoots.
        signed = abs(signed) if flight.status == CRASHED else signed
    return signed, miss


class BankGuidance:
    def __init__(
        self,
        model: EntryModel,
        limits: Limits,
        *,
        sigma_max_rad: float,
        newton_iterations: int,
        newton_tolerance_m: float,
        finite_difference_rad: float,
        violation_weight_m: float,
        terminal_radius_m: float,
        deadline: Deadline | None = None,
    ) -> None:
        self.model = model
        self.terminal_radius_m = terminal_radius_m
        self.limits = limits
        self.sigma_max = sigma_max_rad
        self.newton_iterations = newton_iterations
        self.tolerance = newton_tolerance_m
        self.step = finite_difference_rad
        self.weight = violation_weight_m
        self.deadline = deadline or Deadline.unlimited()

    def shoot(self, sigma0: float, sigma1: float, *, record: bool = False) -> Shot:
        flight = self.model.fly(sigma0, sigma1, record=record)
        signed, miss = range_error(self.model, flight)
        return Shot(sigma0, sigma1, flight, signed, miss, path_excess(flight, self.limits))

    def newton(self, sigma1: float, sigma0_start: float) -> Shot:
        """sigma_0 nulling the range error for this sigma_1 (or the closest bound).

        Newton's iteration with the slope from the last two shots (secant form),
        the first slope from a finite difference.
        """
        lo, hi = 0.0, self.sigma_max
        sigma0 = min(max(sigma0_start, lo), hi)
        shot = self.shoot(sigma0, sigma1)
        best = shot
        h = self.step if sigma0 + self.step <= hi else -self.step
        previous = self.shoot(sigma0 + h, sigma1)
        if abs(previous.range_error_m) < abs(best.range_error_m):
            best = previous
        for iteration in range(1, self.newton_iterations + 1):
            if abs(best.range_error_m) <= self.tolerance or self.deadline.expired():
                break
            d_sigma = previous.sigma0_rad - shot.sigma0_rad
            slope = (previous.range_error_m - shot.range_error_m) / d_sigma if d_sigma else 0.0
            if slope == 0.0 or not math.isfinite(slope):
                break
            new = min(max(shot.sigma0_rad - shot.range_error_m / slope, lo), hi)
            if new in (shot.sigma0_rad, previous.sigma0_rad):
                break  # pinned at a bound: the site is outside the footprint
            previous, shot = shot, self.shoot(new, sigma1)
            shot.newton_iterations = iteration
            if abs(shot.range_error_m) < abs(best.range_error_m):
                best = shot
        else:
            best.newton_exhausted = abs(best.range_error_m) > self.tolerance
        return best

    def objective(self, shot: Shot) -> float:
        """Miss + terminal-altitude error + weighted path-limit excess [m]."""
        altitude_error = abs(shot.flight.state[0] - self.terminal_radius_m)
        return shot.cost_m + altitude_error + self.weight * shot.excess

    def solve(self, sigma1_bounds: tuple[float, float], golden_iterations: int) -> tuple[Shot, int]:
        """Golden section on sigma_1, Newton inside; returns the best shot and the count."""
        a, b = sigma1_bounds
        start = 0.5 * self.sigma_max
        c = b - GOLDEN * (b - a)
        d = a + GOLDEN * (b - a)
        shot_c = self.newton(c, start)
        shot_d = self.newton(d, shot_c.sigma0_rad)
        evaluated = [shot_c, shot_d]
        for _ in range(golden_iterations):
            if self.deadline.expired():
                break
            if self.objective(shot_c) <= self.objective(shot_d):
                b, d, shot_d = d, c, shot_c
                c = b - GOLDEN * (b - a)
                shot_c = self.newton(c, shot_d.sigma0_rad)
                evaluated.append(shot_c)
            else:
                a, c, shot_c = c, d, shot_d
                d = a + GOLDEN * (b - a)
                shot_d = self.newton(d, shot_c.sigma0_rad)
                evaluated.append(shot_d)
        best = min(evaluated, key=self.objective)
        return best, len(evaluated)


def unit_bounds(bounds_deg: tuple[float, float], sigma_max_deg: float) -> tuple[float, float]:
    lo, hi = bounds_deg
    return math.radians(lo), math.radians(min(hi, sigma_max_deg))
