"""The errors of one dispersed run of a plan's Monte Carlo, drawn and applied to a flight
(:mod:`ovtraj.mission.montecarlo`).

Each run draws its errors from its own generator (``numpy.random.default_rng([seed, run])``,
so a run does not depend on how runs are batched), 1-sigma normal, from
``configs/dispersions.yaml`` (:func:`draw_run`):

* the carrier's release (position, altitude, Mach, path angle) and each solid stage's
  delivered thrust and specific impulse (the mass flow follows: ``F / (Isp g0)``);
* the on-board state estimate before the rendezvous, the transfer and the deorbit burn
  (position and velocity, per axis);
* each impulse's execution (magnitude and two transverse pointing angles);
* the atmosphere's density and the vehicle's lift and drag (one factor each per run).

:class:`DispersedFlight` applies them to the replay (:func:`ovtraj.mission.fly.fly_plan`): the
dispersed launcher and release, each impulse executed with its errors, the entry in the
dispersed atmosphere.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ovtraj.config.dispersions import DispersionsConfig
from ovtraj.launch.inputs import LaunchInput
from ovtraj.mission.perturbation import Perturbation
from ovtraj.reentry import dynamics as dyn
from ovtraj.reentry.model import EntryModel

__all__ = [
    "NAVIGATION_POINTS",
    "DispersedFlight",
    "RunDraw",
    "draw_run",
    "pointed",
    "scaled_entry_model",
]

# Where the on-board estimate is drawn: before each corrected phase.
NAVIGATION_POINTS = ("rendezvous", "arrival", "transfer", "deorbit")


@dataclass(frozen=True)
class RunDraw:
    """One run's errors (see the module notes); angles in rad, scales as factors."""

    run: int
    drop_north_m: float
    drop_east_m: float
    drop_altitude_m: float
    drop_mach: float
    drop_fpa_rad: float
    thrust_scale: tuple[float, float, float]
    isp_scale: tuple[float, float, float]
    navigation: dict[str, NDArray[np.float64]]  # (6,) position [m], velocity [m/s]
    burn_scale: tuple[float, ...]  # one per planned impulse
    burn_pointing_rad: tuple[tuple[float, float], ...]
    # The mid-course corrections: the estimate before each and its execution.
    correction_navigation: tuple[NDArray[np.float64], ...]
    correction_scale: tuple[float, ...]
    correction_pointing_rad: tuple[tuple[float, float], ...]
    density_scale: float
    lift_scale: float
    drag_scale: float
    seed: int = 0
    accelerometer_fraction: float = 0.0
    navigation_sigma: tuple[float, float] = (0.0, 0.0)  # position [m], velocity [m/s]

    def retarget_navigation(self, k: int) -> NDArray[np.float64]:
        """The estimate's error (6,) at the ``k``-th re-targeting of the phasing (the
        high-fidelity sky's), drawn from the run's own stream for it."""
        rng = np.random.default_rng([self.seed, self.run, 2, k])
        position, velocity = self.navigation_sigma
        return np.r_[rng.normal(0.0, position, 3), rng.normal(0.0, velocity, 3)]

    def measurement_error(self, call: int) -> NDArray[np.float64]:
        """Relative errors of the measured (lift, drag) at the ``call``-th entry guidance
        call: drawn from the run's own stream for that call, as many calls as the entry
        takes."""
        rng = np.random.default_rng([self.seed, self.run, 1, call])
        return rng.normal(0.0, self.accelerometer_fraction, 2)


def draw_run(config: DispersionsConfig, seed: int, run: int, impulses: int = 5) -> RunDraw:
    """The errors of run ``run`` of the Monte Carlo seeded ``seed`` (1-sigma normal)."""
    rng = np.random.default_rng([seed, run])
    drop, stages, nav = config.drop, config.stages, config.navigation
    burns, entry = config.burns, config.entry
    corrections = len(config.closed_loop.rendezvous_corrections)

    def normal(sigma: float, size: int | None = None) -> Any:
        return rng.normal(0.0, sigma, size)

    return RunDraw(
        run=run,
        drop_north_m=float(normal(drop.position_m)),
        drop_east_m=float(normal(drop.position_m)),
        drop_altitude_m=float(normal(drop.altitude_m)),
        drop_mach=float(normal(drop.mach)),
        drop_fpa_rad=math.radians(float(normal(drop.fpa_deg))),
        thrust_scale=tuple(1.0 + normal(stages.thrust_fraction, 3)),
        isp_scale=tuple(1.0 + normal(stages.isp_fraction, 3)),
        navigation={
            point: np.r_[normal(nav.position_m, 3), normal(nav.velocity_mps, 3)]
            for point in NAVIGATION_POINTS
        },
        burn_scale=tuple(1.0 + normal(burns.magnitude_fraction, impulses)),
        burn_pointing_rad=tuple(
            (float(a), float(b)) for a, b in np.radians(normal(burns.pointing_deg, (impulses, 2)))
        ),
        correction_navigation=tuple(
            np.r_[normal(nav.position_m, 3), normal(nav.velocity_mps, 3)]
            for _ in range(corrections)
        ),
        correction_scale=tuple(1.0 + normal(burns.magnitude_fraction, corrections)),
        correction_pointing_rad=tuple(
            (float(a), float(b))
            for a, b in np.radians(normal(burns.pointing_deg, (corrections, 2)))
        ),
        density_scale=float(max(1.0 + normal(entry.density_fraction), entry.minimum_factor)),
        lift_scale=float(max(1.0 + normal(entry.lift_fraction), entry.minimum_factor)),
        drag_scale=float(max(1.0 + normal(entry.drag_fraction), entry.minimum_factor)),
        seed=int(seed),
        accelerometer_fraction=config.closed_loop.accelerometer_fraction,
        navigation_sigma=(nav.position_m, nav.velocity_mps),
    )


def pointed(dv: NDArray[np.float64], angles: tuple[float, float]) -> NDArray[np.float64]:
    """``dv``'s direction turned by two small angles about two axes normal to it."""
    norm = float(np.linalg.norm(dv))
    if norm == 0.0 or angles == (0.0, 0.0):
        # Unturned exactly: a renormalised copy differs in the last bits, and the replay's
        # adaptive steps turned that into ~0.1 m at the landing of a stored plan.
        return dv.copy()
    u = dv / norm
    helper = np.array([0.0, 0.0, 1.0]) if abs(u[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(u, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    turned = u + math.tan(angles[0]) * e1 + math.tan(angles[1]) * e2
    return norm * turned / np.linalg.norm(turned)


class DispersedFlight(Perturbation):
    """The errors of one draw applied to the replay (:func:`ovtraj.mission.fly.fly_plan`)
    and to the closed loop's flight."""

    def __init__(self, draw: RunDraw) -> None:
        self.draw = draw

    def ascent(self, inp: LaunchInput) -> LaunchInput:
        d = self.draw
        stages = []
        for stage, k_thrust, k_isp in zip(
            inp.launcher.stages, d.thrust_scale, d.isp_scale, strict=True
        ):
            # The propellant burns in m_p Isp g0 / F: the action time follows.
            stages.append(
                stage.model_copy(
                    update={
                        "vacuum_thrust_n": stage.vacuum_thrust_n * k_thrust,
                        "vacuum_isp_s": stage.vacuum_isp_s * k_isp,
                        "burn_time_s": stage.burn_time_s * k_isp / k_thrust,
                    }
                )
            )
        launcher = inp.launcher.model_copy(update={"stages": tuple(stages)})
        radius = inp.earth.radius
        latitude = math.radians(inp.drop.latitude_deg)
        drop = inp.drop.model_copy(
            update={
                "latitude_deg": inp.drop.latitude_deg + math.degrees(d.drop_north_m / radius),
                "longitude_deg": inp.drop.longitude_deg
                + math.degrees(d.drop_east_m / (radius * math.cos(latitude))),
                "altitude_km": inp.drop.altitude_km + d.drop_altitude_m / 1e3,
                "mach": inp.drop.mach + d.drop_mach,
                "flight_path_angle_deg": inp.drop.flight_path_angle_deg
                + math.degrees(d.drop_fpa_rad),
            }
        )
        return replace(inp, launcher=launcher, drop=drop)

    def burn(self, index: int, dv_eci_mps: NDArray[np.float64]) -> NDArray[np.float64]:
        d = self.draw
        return d.burn_scale[index] * pointed(np.asarray(dv_eci_mps), d.burn_pointing_rad[index])

    def entry(self, model: EntryModel) -> EntryModel:
        d = self.draw
        return scaled_entry_model(model, d.density_scale, d.lift_scale, d.drag_scale)


def scaled_entry_model(model: EntryModel, density: float, lift: float, drag: float) -> EntryModel:
    """A copy of ``model`` with its density, lift and drag coefficients scaled."""
    scaled = copy.copy(model)
    scaled.cl = model.cl * lift
    scaled.cd = model.cd * drag
    scaled.log_rho = model.log_rho + math.log(density)
    scaled.params = model.params.copy()
    scaled.params[dyn.P_RHO0] *= density
    scaled.tables = (
        scaled.cl,
        scaled.cd,
        model.mach_nodes,
        model.alpha_nodes,
        scaled.log_rho,
        model.sound,
    )
    return scaled
