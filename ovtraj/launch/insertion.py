"""The insertion the mission chain starts from, and the launch solved to fly there.

The chain takes the launch from the launch fit (patent 5.1): payload, drop-to-insertion
time, insertion epoch and argument of latitude at the parking altitude ``H``. It starts the
OV on a circular orbit there (:func:`circular_insertion_state`):

* ``launch_target``: the orbit the launch stage aims at, its insertion constraints
  (:mod:`ovtraj.launch.problem`): radius ``R_E + H``, circular speed, zero flight-path
  angle, osculating; its *mean* (first-order J2) inclination and node are the plane's,
  as the stage constrains the mean inclination and times the drop on the mean node;
* ``mean_circular``: a circular orbit of J2 mean elements at ``H`` (where runs stored
  without this setting start); its osculating radius at the insertion point lies ~2 km
  below ``R_E + H``.

A plan flies from the carrier's drop, so it needs the launch programme itself. The launch
optimum is flat: programmes within 0.01 kg of the best payload insert up to 0.11 deg of
argument of latitude and 1.4 s apart, and over a 31-45 h phasing wait such a difference
moves the rendezvous by minutes. :func:`solve_launch_to` therefore solves the launch to
*the chain's own insertion*: maximum payload (scipy SLSQP) subject to the insertion's
Earth-fixed position and inertial velocity and the drop-to-insertion time equal to the
chain's (each scaled by its tolerance), and to the path limits. The chain flown from that
launch then starts within millimetres of where the front's evaluation started, so the plan
of a front point flies the figures the front promised (docs/plan.md).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import Bounds, OptimizeResult, minimize

from ovtraj.astro.angles import principal_angle
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.frames import ecef_to_eci, eci_to_ecef
from ovtraj.astro.j2_elements import state_to_mean
from ovtraj.config.launch import DESIGN_VARIABLES
from ovtraj.config.mission import InsertionOrbit, LaunchMatchSettings
from ovtraj.deadline import Deadline
from ovtraj.launch.ascent_optimization import PAYLOAD_INDEX, OptimisationOutcome, PhaseRecord
from ovtraj.launch.inputs import LaunchInput
from ovtraj.launch.problem import LaunchProblem
from ovtraj.launch.result import LaunchResult
from ovtraj.launch.stage import finish_launch, launch_problem
from ovtraj.parallel import EVALUATION_BLAS_THREADS, blas_threads
from ovtraj.target_state import circular_orbit_state

__all__ = [
    "MATCH_PHASE",
    "InsertionPoint",
    "circular_insertion_state",
    "solve_launch_to",
    "turned_east",
]

MATCH_PHASE = "match"
"""The phase a launch solved to an insertion records (its row's ``match_*`` columns)."""

# Fixed-point iterations on the osculating plane whose mean plane is the one asked for: the
# J2 short-period terms of i and the node are ~1e-3 rad, so each iteration gains ~3 digits.
_PLANE_ITERATIONS = 6
_PLANE_TOLERANCE_RAD = 1e-14  # a few ulp of the angles: converged


def circular_insertion_state(
    orbit: InsertionOrbit,
    altitude_m: float,
    arg_latitude_rad: float,
    mean_inclination_rad: float,
    mean_raan_rad: float,
    earth: EarthModel,
) -> NDArray:
    """ECI position [m] and velocity [m/s] of a circular insertion at ``altitude_m`` above
    the spherical Earth, at argument of latitude ``arg_latitude_rad``, in the plane of mean
    inclination and node ``mean_*_rad`` (module notes for ``orbit``)."""
    if orbit == "mean_circular":
        return circular_orbit_state(
            altitude_m,
            mean_inclination_rad,
            mean_raan_rad,
            arg_latitude_rad,
            element_set="mean",
            earth=earth,
        )
    inclination, raan = mean_inclination_rad, mean_raan_rad
    for _ in range(_PLANE_ITERATIONS):
        state = circular_orbit_state(
            altitude_m, inclination, raan, arg_latitude_rad, element_set="osculating", earth=earth
        )
        mean = state_to_mean(state[:3], state[3:], mu=earth.mu, radius=earth.radius, j2=earth.j2)
        di = mean_inclination_rad - float(mean.i)
        draan = principal_angle(mean_raan_rad - float(mean.raan))
        if max(abs(di), abs(draan)) < _PLANE_TOLERANCE_RAD:
            return state
        inclination, raan = inclination + di, raan + draan
    return circular_orbit_state(
        altitude_m, inclination, raan, arg_latitude_rad, element_set="osculating", earth=earth
    )


def turned_east(state: NDArray, angle_rad: float) -> NDArray:
    """The ECI state (m, m/s) turned ``angle_rad`` east about the pole: its node moves east
    by that much and, J2 being axisymmetric, nothing else of its mean elements changes."""
    return np.r_[ecef_to_eci(state[:3], angle_rad), ecef_to_eci(state[3:], angle_rad)]


@dataclass(frozen=True)
class InsertionPoint:
    """Where and when the launch must insert: ``t_s`` [s from the launch day's 0 h], the
    drop-to-insertion ``flight_time_s`` [s] and the ECI ``state`` (m, m/s)."""

    t_s: float
    flight_time_s: float
    state: NDArray

    def earth_fixed(self, theta0_rad: float, omega_rad_s: float) -> tuple[NDArray, NDArray]:
        """Earth-fixed position [m] and inertial velocity in Earth-fixed axes [m/s] (what
        the ascent ends with), the Earth rotation angle being ``theta0 + omega t``."""
        theta = theta0_rad + omega_rad_s * self.t_s
        return eci_to_ecef(self.state[:3], theta), eci_to_ecef(self.state[3:], theta)


def solve_launch_to(
    inp: LaunchInput,
    point: InsertionPoint,
    seed_design: dict[str, float],
    settings: LaunchMatchSettings,
) -> LaunchResult:
    """Maximum-payload launch that inserts at ``point`` (module notes), from ``seed_design``
    (configuration units). ``inp.target_plane`` is the plane the point lies in (the timing
    of the result's node error). Never raises on a numerical failure: the result is
    infeasible with the reason (a match not reached names each miss and its tolerance).
    One BLAS thread whatever the process's pools, as :func:`~ovtraj.launch.stage.solve_launch`."""
    with blas_threads(EVALUATION_BLAS_THREADS):
        return _solve_to(inp, point, seed_design, settings)


def _solve_to(
    inp: LaunchInput,
    point: InsertionPoint,
    seed_design: dict[str, float],
    settings: LaunchMatchSettings,
) -> LaunchResult:
    start = time.perf_counter()
    try:
        problem = launch_problem(inp)
    except ValueError as err:
        return LaunchResult.infeasible(inp, str(err))
    match = _Match(problem, point, inp, settings)
    deadline = Deadline(settings.time_limit_s, "mission.insertion.launch_match.time_limit_s")
    x0 = np.clip(problem.to_scaled(np.array([seed_design[k] for k in DESIGN_VARIABLES])), 0, 1)
    before = problem.trajectories
    try:
        with np.errstate(all="ignore"):
            result = _maximum_payload(problem, match, x0, settings, deadline)
            x = _polished(np.clip(result.x, 0.0, 1.0), match, settings.polish_iterations)
            miss, _, paths, _ = match(x)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as err:
        return LaunchResult.infeasible(inp, f"numerical failure: {type(err).__name__}: {err}")
    violations = _misses(miss, paths / match.margin)
    limit = deadline.reason(int(result.nit)) if deadline.reached else None
    if limit is None and not result.success and violations:
        violations.append(f"SLSQP: {result.message}")
    wall = time.perf_counter() - start
    outcome = _match_outcome(problem, x, result, miss, violations, limit, before, wall)
    return finish_launch(
        inp, problem, outcome, wall, insertion_time=point.t_s, violations=violations
    )


class _Match:
    """The insertion constraints of a design ``x`` (scaled): the misses of the Earth-fixed
    position, inertial velocity and drop-to-insertion time from ``point``'s, each over its
    tolerance, the path margins, and their central-difference Jacobians."""

    def __init__(
        self,
        problem: LaunchProblem,
        point: InsertionPoint,
        inp: LaunchInput,
        settings: LaunchMatchSettings,
    ) -> None:
        self.problem = problem
        self.flight_time_s = point.flight_time_s
        self.r_fixed, self.v_fixed = point.earth_fixed(inp.launch_day.gmst_rad(), inp.earth.omega)
        self.scale = np.r_[
            [settings.position_tolerance_m] * 3,
            [settings.velocity_tolerance_mps] * 3,
            settings.flight_time_tolerance_s,
        ]
        self.n, self.step = problem.dimension, inp.local.finite_difference_step
        self.margin = problem.target.path_limit_fraction
        self._key: bytes | None = None
        self._values: tuple[NDArray, NDArray, NDArray, NDArray]

    def __call__(self, x: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """Scaled misses and path margins of ``x``, and their central-difference Jacobians,
        from one batch of 2n + 1 ascents (cached for the last point)."""
        key = np.asarray(x, dtype=float).tobytes()
        if self._key != key:
            n, step = self.n, self.step
            rows = np.vstack([x, x + step * np.eye(n), x - step * np.eye(n)])
            ev = self.problem.evaluate(rows)
            asc = ev.outcome
            miss = (
                np.c_[
                    asc.r_ecef - self.r_fixed,
                    asc.v_inertial_ecef_axes - self.v_fixed,
                    asc.time_s - self.flight_time_s,
                ]
                / self.scale
            )
            paths = ev.inequality * self.margin  # 1 - q_max / q_limit, 1 - n_max / n_limit
            self._key = key
            self._values = (
                miss[0],
                ((miss[1 : n + 1] - miss[n + 1 :]) / (2 * step)).T,
                paths[0],
                ((paths[1 : n + 1] - paths[n + 1 :]) / (2 * step)).T,
            )
        return self._values


def _match_outcome(
    problem: LaunchProblem,
    x: NDArray,
    result: OptimizeResult,
    miss: NDArray,
    violations: list[str],
    limit: str | None,
    trajectories_before: int,
    wall_time_s: float,
) -> OptimisationOutcome:
    """The solved design ``x`` as the launch optimiser's outcome: one phase, the match."""
    payload = float(problem.to_config_units(x)[PAYLOAD_INDEX])
    record = PhaseRecord(
        name=MATCH_PHASE,
        payload_kg=payload,
        max_violation=float(max(np.max(np.abs(miss)) - 1.0, 0.0)),
        max_residual=float(np.max(np.abs(miss))),
        feasible=not violations,
        accepted=True,
        iterations=int(result.nit),
        trajectories=problem.trajectories - trajectories_before,
        wall_time_s=wall_time_s,
        message=str(result.message),
    )
    return OptimisationOutcome(
        x=x,
        payload_kg=payload,
        max_violation=record.max_violation,
        max_residual=record.max_residual,
        phases=[record],
        trajectories=problem.trajectories,
        wall_time_s=wall_time_s,
        limit=limit,
    )


def _maximum_payload(
    problem: LaunchProblem,
    match: _Match,
    x0: NDArray,
    settings: LaunchMatchSettings,
    deadline: Deadline,
) -> OptimizeResult:
    """SLSQP from ``x0`` (scaled): the largest payload within the match and path limits."""
    n = problem.dimension
    # Payload in kg: the objective's scale, so that ftol is a change of payload.
    payload_span = float(problem.upper[PAYLOAD_INDEX] - problem.lower[PAYLOAD_INDEX])
    gradient = np.zeros(n)
    gradient[PAYLOAD_INDEX] = -payload_span
    return minimize(
        lambda x: -payload_span * float(x[PAYLOAD_INDEX]),
        x0,
        jac=lambda x: gradient,
        method="SLSQP",
        bounds=Bounds(np.zeros(n), np.ones(n)),
        constraints=[
            {"type": "eq", "fun": lambda x: match(x)[0], "jac": lambda x: match(x)[1]},
            {"type": "ineq", "fun": lambda x: match(x)[2], "jac": lambda x: match(x)[3]},
        ],
        options={"maxiter": settings.max_iterations, "ftol": settings.payload_ftol_kg},
        callback=lambda _: deadline.stop_if_expired(),
    )


def _polished(x: NDArray, match: Callable, iterations: int) -> NDArray:
    """Least-norm Gauss-Newton steps on the scaled misses, the payload held, while any miss
    exceeds its tolerance: SLSQP trades the last centimetres against grams of payload on
    the flat optimum and may stop at its iteration limit just outside the tolerances."""
    free = np.arange(len(x)) != PAYLOAD_INDEX
    for _ in range(iterations):
        miss, jacobian, _, _ = match(x)
        if np.max(np.abs(miss)) <= 1.0:
            break
        step = np.linalg.lstsq(jacobian[:, free], -miss, rcond=None)[0]
        x = x.copy()
        x[free] = np.clip(x[free] + step, 0.0, 1.0)
    return x


_MISS_NAMES = (
    ("position x", "m"),
    ("position y", "m"),
    ("position z", "m"),
    ("velocity x", "m/s"),
    ("velocity y", "m/s"),
    ("velocity z", "m/s"),
    ("flight time", "s"),
)


def _misses(scaled_miss: NDArray, scaled_paths: NDArray) -> list[str]:
    """A reason per miss beyond its tolerance and per path limit exceeded beyond its."""
    reasons = [
        f"insertion {name} misses the chain's by {value:.3g} tolerances ({unit})"
        for (name, unit), value in zip(_MISS_NAMES, scaled_miss, strict=True)
        if abs(value) > 1.0
    ]
    reasons += [
        f"{name} over its limit by {-value:.3g} tolerances"
        for name, value in zip(("dynamic pressure", "axial load"), scaled_paths, strict=True)
        if value < -1.0
    ]
    return reasons
