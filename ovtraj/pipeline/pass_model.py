"""A low-fidelity T_total: the deorbit's pass predicted from the design.

T_total moves in whole days: the deorbit waits for a pass of the ground track through the
entry region, and which pass comes first depends on when the OV reaches its preparation
orbit and where it is on it. A regressor smears those steps; this model places them. From
a design (H_P0, H_dp, t_dsp), with no integration:

1. the launch fit gives the drop and insertion times at H_P0 (the chain's own series);
2. the rendezvous arrives after the phasing wait (the surrogates' wait model, a function of
   H_P0 alone) plus ``rendezvous_transfer_fraction`` of the Hohmann time to the target;
3. the OV leaves the target after the stay and t_dsp, on the target's orbit (J2 secular
   mean elements), and reaches H_dp ``transfer_fraction`` of a Hohmann time later, half a
   revolution on, in the target's plane;
4. :func:`ovtraj.deorbit.pass_estimate.first_pass_s` gives the first usable pass there.

``T_lf = pass - drop + offset``; the offset (the descent and the entry after the pass,
~0.5 h) is the median of the chain's samples' ``T_total - (pass - drop)``. Measured on 71
designs of the default scenario (docs/optimize.md): that difference is 0.46-0.50 h on 63,
and a whole number of days more on the others (a pass the chain's deorbit did not take).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from functools import cached_property
from typing import Any

import numpy as np

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import NonsingularElements
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.j2_elements import secular_rates, state_to_mean
from ovtraj.config import Scenario
from ovtraj.config.deorbit import DeorbitSolverConfig
from ovtraj.deorbit.inputs import EntryRegion, deorbit_input
from ovtraj.deorbit.pass_estimate import first_pass_s
from ovtraj.launch.fourier import FourierSeries
from ovtraj.mission.plane import aimed_node_offset, drop_delay_s
from ovtraj.rendezvous.hohmann import hohmann_time_s
from ovtraj.target_state import target_state
from ovtraj.units import S_PER_HOUR


def usable_burn_lead_s(solver: DeorbitSolverConfig) -> float:
    """How long [s] before the preparation orbit begins a pass's tangential burn may fall
    while the stage still takes that pass. With ``pass_cost_margin_mps`` none: the burn
    would be pinned at the start and steered at a price the stage refuses, so it waits for
    the next pass (T_total within 0.1 h on 486 of 489 feasible random designs, against 479
    when the correction's burn window is allowed; docs/optimize.md). Without the margin the
    stage tries a pass whose burn falls within its correction window of the start."""
    return 0.0 if solver.pass_cost_margin_mps is not None else solver.burn_window_s


def target_mean_elements(scenario: Scenario) -> NonsingularElements:
    """The target's Brouwer mean elements (J2) at the scenario epoch."""
    earth = scenario.earth
    state = target_state(scenario.target.orbit, scenario)
    return state_to_mean(state[:3], state[3:], mu=earth.mu, radius=earth.radius, j2=earth.j2)


@dataclass(frozen=True)
class TargetMeanMotion:
    """The target's J2 secular mean orbit from the launch day's 0 h: a [m], angles [rad],
    rates [rad/s] (Brouwer 1959 via :func:`ovtraj.astro.j2_elements.secular_rates`)."""

    a_m: float
    inclination_rad: float
    u0_rad: float  # mean argument of latitude at the launch day's 0 h
    raan0_rad: float
    u_rate: float
    raan_rate: float
    argp0_rad: float  # mean argument of perigee at the launch day's 0 h
    argp_rate: float


def target_mean_motion(scenario: Scenario) -> TargetMeanMotion:
    """:class:`TargetMeanMotion` of the scenario's target, from its mean elements."""
    earth = scenario.earth
    day = Epoch.from_iso(scenario.launch.launch_date_utc)
    mean = target_mean_elements(scenario)
    e = math.hypot(float(mean.ex), float(mean.ey))
    raan_rate, argp_rate, m_rate = secular_rates(
        float(mean.a), e, float(mean.i), mu=earth.mu, radius=earth.radius, j2=earth.j2
    )
    offset = day.seconds_since(scenario.epoch)  # the target's state is at the epoch
    u_rate = float(argp_rate) + float(m_rate)
    return TargetMeanMotion(
        a_m=float(mean.a),
        inclination_rad=float(mean.i),
        u0_rad=float(mean.u) + u_rate * offset,
        raan0_rad=float(mean.raan) + float(raan_rate) * offset,
        u_rate=u_rate,
        raan_rate=float(raan_rate),
        argp0_rad=math.atan2(float(mean.ey), float(mean.ex)) + float(argp_rate) * offset,
        argp_rate=float(argp_rate),
    )


@dataclass(frozen=True)
class PassModel:
    """Everything the low-fidelity T_total needs; times in s from the launch day's 0 h."""

    earth: dict[str, float]
    entry: dict[str, Any]
    insertion_time: dict[str, Any]  # launch fit series [s] against H_P0 [m]
    flight_time: dict[str, Any]  # launch fit series [s] against H_P0 [m]
    target_a_m: float
    target_inclination_rad: float
    target_u0_rad: float  # mean argument of latitude at t = 0
    target_raan0_rad: float
    target_u_rate: float  # rad/s, J2 secular
    target_raan_rate: float
    earth_angle_at_zero_rad: float
    stay_s: float
    horizon_s: float
    # How long before the preparation orbit's start a pass's burn may fall and the pass
    # still be taken (:func:`usable_burn_lead_s`).
    burn_window_s: float
    rendezvous_transfer_fraction: float
    transfer_fraction: float
    # After the pass: the descent and the entry to the terminal point, learned from the
    # chain's samples (:meth:`calibrated`); 0 until then.
    offset_s: float = 0.0
    # Added to each crossing's longitude before the entry box is checked (the setting's
    # longitude_shift_deg); 0 in the models stored before it.
    longitude_shift_rad: float = 0.0
    # The target's mean argument of perigee at t = 0 and its J2 rate (the departure
    # phase, :meth:`departure_phase_rad`); 0 in the models stored before them.
    target_argp0_rad: float = 0.0
    target_argp_rate: float = 0.0
    # The launch aims at the target's plane at the rendezvous
    # (ovtraj/mission/plane.py): the drop and the insertion come later by the aimed node's
    # turn; False in the models stored before it.
    aimed_plane: bool = False

    @classmethod
    def of(
        cls, scenario: Scenario, insertion_time: FourierSeries, flight_time: FourierSeries
    ) -> PassModel:
        """The model of a scenario with its launch fit's series."""
        settings = scenario.mission.surrogate.pass_forecast
        day = Epoch.from_iso(scenario.launch.launch_date_utc)
        target = target_mean_motion(scenario)
        deorbit = deorbit_input(scenario, state0=np.zeros(6), epoch=day)
        return cls(
            earth=scenario.earth.model_dump(mode="json"),
            entry=asdict(deorbit.entry),
            insertion_time=insertion_time.to_dict(),
            flight_time=flight_time.to_dict(),
            target_a_m=target.a_m,
            target_inclination_rad=target.inclination_rad,
            target_u0_rad=target.u0_rad,
            target_raan0_rad=target.raan0_rad,
            target_u_rate=target.u_rate,
            target_raan_rate=target.raan_rate,
            earth_angle_at_zero_rad=day.gmst_rad(),
            stay_s=S_PER_HOUR * scenario.mission.stay_h,
            horizon_s=deorbit.horizon_s,
            burn_window_s=usable_burn_lead_s(deorbit.solver),
            rendezvous_transfer_fraction=settings.rendezvous_transfer_fraction,
            transfer_fraction=settings.transfer_fraction,
            longitude_shift_rad=math.radians(settings.longitude_shift_deg),
            target_argp0_rad=target.argp0_rad,
            target_argp_rate=target.argp_rate,
            aimed_plane=scenario.mission.insertion is not None
            and scenario.mission.insertion.plane == "rendezvous",
        )

    def calibrated(
        self, designs: np.ndarray, wait_s: np.ndarray, t_total_s: np.ndarray
    ) -> PassModel:
        """This model with ``offset_s`` the median of the samples' T_total minus the
        model's: the median, because where the model takes another pass than the chain
        the difference is a whole number of days, which a mean or a regressor would spread
        over the others (measured, docs/optimize.md)."""
        base = replace(self, offset_s=0.0)
        residual = np.asarray(t_total_s, dtype=float) - base.t_total_s(designs, wait_s)
        known = np.isfinite(residual)
        if not known.any():
            raise ValueError("no sample with a T_total to calibrate the pass model on")
        return replace(self, offset_s=float(np.median(residual[known])))

    # Built once per model, not on each call (NSGA-II predicts every generation).
    @cached_property
    def _earth(self) -> EarthModel:
        return EarthModel(**self.earth)

    @cached_property
    def _entry(self) -> EntryRegion:
        return EntryRegion(**self.entry)

    @cached_property
    def _series(self) -> tuple[FourierSeries, FourierSeries]:
        return FourierSeries.from_dict(self.insertion_time), FourierSeries.from_dict(
            self.flight_time
        )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PassModel:
        return cls(**data)

    def t_total_s(self, designs: np.ndarray, wait_s: np.ndarray) -> np.ndarray:
        """Low-fidelity T_total [s] of designs (m, 3) whose phasing waits are ``wait_s``
        (m,): to the pass, plus ``offset_s``. Where no usable pass lies in the deorbit's
        horizon (the chain's deorbit finds none either: infeasible), the horizon's end."""
        passes, start, drop = self._passes(designs, wait_s)
        reached = np.where(np.isfinite(passes), passes, start + self.horizon_s)
        return reached - drop + self.offset_s

    def has_pass(self, designs: np.ndarray, wait_s: np.ndarray) -> np.ndarray:
        """Whether a usable pass lies within the deorbit's horizon, per design (m,): where
        none does, the chain's deorbit finds none either (28 of its 29 such designs among
        518 random ones, and one more predicted; docs/optimize.md)."""
        return np.isfinite(self._passes(designs, wait_s)[0])

    def _passes(
        self, designs: np.ndarray, wait_s: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each design's first usable pass (NaN: none), the start of its preparation orbit
        and its drop [s from the launch day's 0 h]."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        earth = self._earth
        mu = earth.mu
        parking = 1e3 * designs[:, 0]
        insertion, drop = self._insertion_and_drop(parking, wait_s)
        separation = self._separation_s(designs, wait_s, insertion)
        preparation_radius = earth.radius + 1e3 * designs[:, 1]
        transfer = self.transfer_fraction * hohmann_time_s(self.target_a_m, preparation_radius, mu)
        start = separation + transfer
        passes = first_pass_s(
            start,
            self.target_u0_rad + self.target_u_rate * separation + math.pi,
            self.target_raan0_rad + self.target_raan_rate * start,
            self.target_inclination_rad,
            preparation_radius,
            entry=self._entry,
            earth=earth,
            earth_angle_at_zero_rad=self.earth_angle_at_zero_rad,
            horizon_s=self.horizon_s,
            burn_window_s=self.burn_window_s,
            longitude_shift_rad=self.longitude_shift_rad,
        )
        return passes, start, drop

    def departure_phase_rad(self, designs: np.ndarray, wait_s: np.ndarray) -> np.ndarray:
        """The target's mean argument of latitude from its perigee [rad] when the OV of
        designs (m, 3) with phasing waits ``wait_s`` leaves it (J2 secular elements): where
        on the target's slightly eccentric orbit the transfer to H_dp starts."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        insertion, _ = self._insertion_and_drop(1e3 * designs[:, 0], wait_s)
        separation = self._separation_s(designs, wait_s, insertion)
        u = self.target_u0_rad + self.target_u_rate * separation
        return u - (self.target_argp0_rad + self.target_argp_rate * separation)

    def _insertion_and_drop(
        self, parking_m: np.ndarray, wait_s: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The insertion and drop times [s] at parking altitudes [m]: the launch fit's, and
        with the plane aimed at the rendezvous the drop later by the aimed node's turn,
        ``(dOmega_T/dt - dOmega_P/dt)(wait + T_H / 2) / (omega_E - dOmega_T/dt)``
        (:mod:`ovtraj.mission.plane`, J2 secular rates of circular orbits)."""
        insertion_series, flight_series = self._series
        insertion = np.asarray(insertion_series(parking_m), float)
        if self.aimed_plane:
            earth = self._earth
            radius = earth.radius + parking_m
            parking_rate, _, _ = secular_rates(
                radius,
                0.0,
                self.target_inclination_rad,
                mu=earth.mu,
                radius=earth.radius,
                j2=earth.j2,
            )
            node = aimed_node_offset(
                self.target_raan_rate - np.asarray(parking_rate, float),
                np.asarray(wait_s, float),
                hohmann_time_s(radius, self.target_a_m, earth.mu),
            )
            insertion = insertion + drop_delay_s(node, earth.omega, self.target_raan_rate)
        return insertion, insertion - np.asarray(flight_series(parking_m), float)

    def _separation_s(
        self, designs: np.ndarray, wait_s: np.ndarray, insertion: np.ndarray
    ) -> np.ndarray:
        """When the OV leaves the target [s]: the rendezvous's arrival after the wait and
        ``rendezvous_transfer_fraction`` Hohmann times, then the stay and t_dsp."""
        earth = self._earth
        arrival = (
            insertion
            + np.asarray(wait_s, dtype=float)
            + self.rendezvous_transfer_fraction
            * hohmann_time_s(earth.radius + 1e3 * designs[:, 0], self.target_a_m, earth.mu)
        )
        return arrival + self.stay_s + S_PER_HOUR * designs[:, 2]
