"""Entry requirements -> transfer-orbit requirements, and the single-burn condition (seed sec. 1).

Ignoring out-of-plane motion, the entry latitude is fixed by the entry argument of latitude
u_E (seed eq. 1, phi_E = asin(sin i_E sin u_E)), and the entry altitude, inertial speed and
flight-path angle at u_E fix the in-plane shape of the transfer (descent) orbit: its a, e and
argp (seed eqs. 2-3). With r_E, v_E, gamma_E (two-body, Curtis 2014, "Orbital Mechanics for
Engineering Students", 3rd ed., sec. 2.4-2.5, 2.7)::

    1/a = 2/r_E - v_E^2/mu                       (vis-viva)
    p = (r_E v_E cos gamma_E)^2 / mu             (h = r v_t)
    e cos f_E = p/r_E - 1,   e sin f_E = v_E sin gamma_E sqrt(p/mu)
    argp = u_E - f_E

the seed's eq. 2 (r_E = p / (1 + e cos(u_E - argp))) and eq. 3 (v_r = sqrt(mu/p) e sin f,
v_t = sqrt(mu/p)(1 + e cos f), tan gamma = v_r / v_t) solved for the elements.

A single impulse reaches the transfer orbit only where the waiting orbit meets it; for a
circular waiting orbit of radius r_0 that is r_p <= r_0 <= a (1 + e) (seed eq. 4: the waiting
orbit must not lie above the transfer orbit's apoapsis). For an elliptic waiting orbit the
condition is that the intersection equation (seed eq. 6) has a root, see
:mod:`ovtraj.studies.deorbit_burn.intersection`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ovtraj.astro.angles import wrap_to_two_pi
from ovtraj.astro.constants import EarthConstants
from ovtraj.astro.elements import NonsingularElements
from ovtraj.astro.j2_elements import osculating_to_mean
from ovtraj.studies.deorbit_burn.problem import EntryTarget

__all__ = ["TransferOrbit", "mean_transfer_orbit", "transfer_orbit"]


@dataclass(frozen=True)
class TransferOrbit:
    """The two-body transfer orbit through the entry point.

    a [m], e [-], argp [rad], p [m] (semi-latus rectum), entry_true_anomaly [rad] in
    (pi, 2 pi) (descending branch), apoapsis radius [m].
    """

    a: float
    e: float
    argp: float
    p: float
    entry_true_anomaly: float

    @property
    def ex(self) -> float:
        return self.e * math.cos(self.argp)

    @property
    def ey(self) -> float:
        return self.e * math.sin(self.argp)

    @property
    def apoapsis_radius(self) -> float:
        return self.a * (1.0 + self.e)


def transfer_orbit(entry: EntryTarget, mu: float) -> TransferOrbit:
    """The transfer orbit's a, e, argp from the entry requirements (seed eqs. 2-3, see above).

    ``entry`` in SI (r_E [m], v_E [m/s], gamma_E [rad] < 0, u_E [rad]); mu [m^3/s^2].
    Raises ``ValueError`` if the entry speed is not elliptic (v_E^2 >= 2 mu / r_E).
    """
    r, v, gamma = entry.radius_m, entry.speed_mps, entry.fpa_rad
    inv_a = 2.0 / r - v * v / mu
    if inv_a <= 0.0:
        raise ValueError(
            f"entry speed {v:.1f} m/s is at or above escape speed at r_E = {r / 1e3:.3f} km"
        )
    p = (r * v * math.cos(gamma)) ** 2 / mu
    e_cos_f = p / r - 1.0
    e_sin_f = v * math.sin(gamma) * math.sqrt(p / mu)
    f = wrap_to_two_pi(math.atan2(e_sin_f, e_cos_f))
    return TransferOrbit(
        a=1.0 / inv_a,
        e=math.hypot(e_cos_f, e_sin_f),
        argp=entry.u_rad - f,
        p=p,
        entry_true_anomaly=f,
    )


def mean_transfer_orbit(
    transfer: TransferOrbit, entry: EntryTarget, i: float, raan: float, earth: EarthConstants
) -> NonsingularElements:
    """First-order J2 mean elements of the transfer orbit at the entry point.

    The entry requirements are osculating (instantaneous) values; the seed's initial burn
    solution (sec. 2.1) works on mean elements, so the transfer orbit is converted with the
    Brouwer-Lyddane short-period terms (:func:`ovtraj.astro.j2_elements.osculating_to_mean`)
    in the waiting orbit's plane (i, raan [rad]). The secular drift of argp between the burn
    and the entry (~0.1 deg) is left to the iteration on the burn start.
    """
    osc = NonsingularElements(
        a=transfer.a, ex=transfer.ex, ey=transfer.ey, i=i, raan=raan, u=entry.u_rad
    )
    return osculating_to_mean(osc, mu=earth.mu, radius=earth.radius, j2=earth.j2)
