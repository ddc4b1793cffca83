"""Where the rendezvous's first burn falls, from the design in closed form.

The chaser is inserted into the target's mean plane, but at a lower altitude its J2
nodal regression is faster, so by the first burn the two planes differ (0.44-0.45 deg on
the default scenario). The rendezvous then pays, above its Hohmann cost, for the
cross-track part of that plane difference, and how much depends on where on the orbit
the burns fall relative to the line where the planes cross, i.e. on the chaser's
argument of latitude at the burn modulo half a revolution. Measured on 760 chain
rendezvous over H_P0 = 250-340 km (docs/optimize.md): ``dV - Hohmann`` ranges over
24-72 m/s, and within 5-degree bins of that angle at the burn epoch given here its
spread is 4.1 m/s (3.5 m/s at the stage's refined epoch; 6.6 m/s at the corrected one).

From a design's H_P0 alone, with no integration (the same steps as the stage's phasing,
:mod:`ovtraj.rendezvous.phasing`, on J2 secular mean elements):

1. the launch fit gives the insertion time and argument of latitude u_ins at H_P0, in
   the target's mean plane, on a circular orbit of radius R + H_P0;
2. the target's mean argument of latitude then leads by phase0 = u_T(t_ins) - u_ins;
3. the burn comes once that lead has closed to pi - n_T T_H (the target's sweep during
   the Hohmann time T_H; Vallado, 4th ed., eq. 6-29) at the J2 rate difference
   (:func:`~ovtraj.rendezvous.phasing.first_wait`);
4. u_burn = u_ins + (argp_dot + M_dot) wait.

The surrogates' phase input is then ``2 u_burn`` (:meth:`BurnPhaseModel.phase_rad`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ovtraj.astro.j2_elements import secular_rates
from ovtraj.config import Scenario
from ovtraj.launch.fourier import FourierSeries
from ovtraj.pipeline.pass_model import target_mean_motion
from ovtraj.rendezvous.hohmann import hohmann_time_s
from ovtraj.rendezvous.phasing import first_wait


@dataclass(frozen=True)
class BurnPhaseModel:
    """The closed-form burn epoch and position of the rendezvous; times in s from the
    launch day's 0 h, angles in rad."""

    mu: float
    radius_m: float
    j2: float
    insertion_time: dict[str, Any]  # launch fit series [s] against H_P0 [m]
    insertion_u: dict[str, Any]  # launch fit series [deg] against H_P0 [m]
    target_a_m: float
    inclination_rad: float
    target_u0_rad: float
    target_u_rate: float

    @classmethod
    def of(
        cls, scenario: Scenario, insertion_time: FourierSeries, insertion_u: FourierSeries
    ) -> BurnPhaseModel:
        """The model of a scenario with its launch fit's series."""
        earth, target = scenario.earth, target_mean_motion(scenario)
        return cls(
            mu=earth.mu,
            radius_m=earth.radius,
            j2=earth.j2,
            insertion_time=insertion_time.to_dict(),
            insertion_u=insertion_u.to_dict(),
            target_a_m=target.a_m,
            inclination_rad=target.inclination_rad,
            target_u0_rad=target.u0_rad,
            target_u_rate=target.u_rate,
        )

    @cached_property
    def _series(self) -> tuple[FourierSeries, FourierSeries]:
        return FourierSeries.from_dict(self.insertion_time), FourierSeries.from_dict(
            self.insertion_u
        )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> BurnPhaseModel:
        return cls(**data)

    def burn(self, parking_altitude_km: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(phasing wait [s], the chaser's mean argument of latitude at the burn [rad])
        of parking altitudes (m,) [km]."""
        parking = 1e3 * np.asarray(parking_altitude_km, dtype=float)
        insertion_series, u_series = self._series
        t_insertion = np.asarray(insertion_series(parking), dtype=float)
        u_insertion = np.radians(np.asarray(u_series(parking), dtype=float))
        a_chaser = self.radius_m + parking
        _, argp_rate, m_rate = secular_rates(
            a_chaser, 0.0, self.inclination_rad, mu=self.mu, radius=self.radius_m, j2=self.j2
        )
        u_rate = np.asarray(argp_rate + m_rate, dtype=float)
        phase0 = self.target_u0_rad + self.target_u_rate * t_insertion - u_insertion
        # The lead angle unwrapped: first_wait takes the gap modulo 2 pi.
        lead = math.pi - self.target_u_rate * hohmann_time_s(a_chaser, self.target_a_m, self.mu)
        wait = np.asarray(first_wait(phase0, lead, u_rate - self.target_u_rate), dtype=float)
        return wait, u_insertion + u_rate * wait

    def phase_rad(self, designs: np.ndarray) -> np.ndarray:
        """The phase input [rad] of designs (m, 3): twice the burn's argument of latitude,
        so that its sine and cosine repeat every half revolution, as the planes' crossing
        line does."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        return 2.0 * self.burn(designs[:, 0])[1]
