"""Lifting-entry equations of motion as CasADi expressions (exact NLP derivatives).

Time domain, states ``(h, lon, lat, V, gamma, psi)`` with ``r = R + h``, heading from
north clockwise, controls angle of attack ``alpha`` and bank ``sigma`` (Vinh, Busemann &
Culp, *Hypersonic and Planetary Entry Flight Mechanics*, 1980, ch. 2; seed 001 eqs. 1-6
are the case ``Omega = 0``)::

    h'     = V sin(gamma)
    lon'   = V cos(gamma) sin(psi) / (r cos(lat))
    lat'   = V cos(gamma) cos(psi) / r
    V'     = -D - g sin(gamma) + Omega^2 r cos(lat) (sin(gamma) cos(lat)
             - cos(gamma) sin(lat) cos(psi))
    gamma' = [L cos(sigma) + (V^2 / r - g) cos(gamma) + 2 Omega V cos(lat) sin(psi)
             + Omega^2 r cos(lat) (cos(gamma) cos(lat) + sin(gamma) cos(psi) sin(lat))] / V
    psi'   = [L sin(sigma) / cos(gamma) + V^2 / r cos(gamma) sin(psi) tan(lat)
             - 2 Omega V (tan(gamma) cos(psi) cos(lat) - sin(lat))
             + Omega^2 r sin(psi) sin(lat) cos(lat) / cos(gamma)] / V

with lift and drag accelerations ``L = q S C_L / m``, ``D = q S C_D / m`` and
``q = rho V^2 / 2`` (seed eq. 7), ``C = sum_ij c_ij alpha^i Ma^j``, gravity ``mu / r^2`` or
``g0``. Path quantities: normal load ``(L cos(alpha) + D sin(alpha)) / g0`` (body-normal
axis, SPEC step 4) or total load ``sqrt(L^2 + D^2) / g0``; heat rate
``k rho^m V^n P(alpha)`` (Sutton & Graves, NASA TR R-376, 1971, for ``m = 1/2``, ``n = 3``;
the general power form of e.g. Lu, JGCD 37(4), 2014, with a polynomial in alpha).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from ovtraj.studies.optimal_entry.problem import EntryProblem

__all__ = ["AeroValues", "EntryExpressions"]


@dataclass(frozen=True)
class AeroValues:
    """Aerodynamic and path quantities at one node (SI; load in g)."""

    rho: ca.SX
    mach: ca.SX
    cl: ca.SX
    cd: ca.SX
    dynamic_pressure: ca.SX
    lift: ca.SX  # acceleration [m/s^2]
    drag: ca.SX
    heat_rate: ca.SX  # W/m^2
    load_g: ca.SX


def _poly2(c: list[list[float]], x: ca.SX, y: ca.SX) -> ca.SX:
    """``sum_ij c[i][j] x^i y^j`` by nested Horner's rule."""
    total = ca.SX(0.0)
    for row in reversed(c):
        inner = ca.SX(0.0)
        for coefficient in reversed(row):
            inner = inner * y + float(coefficient)
        total = total * x + inner
    return total


def _poly(c: list[float], x: ca.SX) -> ca.SX:
    total = ca.SX(0.0)
    for coefficient in reversed(c):
        total = total * x + float(coefficient)
    return total


class EntryExpressions:
    """The entry model of one problem as functions of CasADi expressions."""

    def __init__(self, problem: EntryProblem) -> None:
        self.p = problem
        self._cl = problem.cl.tolist()
        self._cd = problem.cd.tolist()
        self._heat_poly = problem.heat_alpha_polynomial.tolist()

    def gravity(self, h: ca.SX) -> ca.SX:
        p = self.p
        if p.gravity == "constant":
            return ca.SX(p.g0)
        return p.mu / (p.radius + h) ** 2

    def aero(self, h: ca.SX, v: ca.SX, alpha: ca.SX) -> AeroValues:
        p = self.p
        rho, sound = p.nlp_atmosphere.evaluate(h)
        mach = v / sound
        a = alpha * p.alpha_scale
        cl = _poly2(self._cl, a, mach)
        cd = _poly2(self._cd, a, mach)
        q = 0.5 * rho * v**2
        lift = q * p.area * cl / p.mass
        drag = q * p.area * cd / p.mass
        if p.heat_coefficient is not None:
            heat = (
                p.heat_coefficient
                * rho**p.heat_density_exponent
                * v**p.heat_speed_exponent
                * _poly(self._heat_poly, a)
            )
        else:
            heat = ca.SX(0.0)
        if p.load_definition == "normal":
            load = (lift * ca.cos(alpha) + drag * ca.sin(alpha)) / p.g0
        else:
            load = ca.sqrt(lift**2 + drag**2) / p.g0
        return AeroValues(rho, mach, cl, cd, q, lift, drag, heat, load)

    def time_rates(
        self,
        h: ca.SX,
        lat: ca.SX,
        v: ca.SX,
        gamma: ca.SX,
        psi: ca.SX,
        bank: ca.SX,
        av: AeroValues,
    ) -> list[ca.SX]:
        """d/dt of ``(h, lon, lat, V, gamma, psi)`` (module notes)."""
        p = self.p
        r = p.radius + h
        g = self.gravity(h)
        w = p.omega
        sg, cg = ca.sin(gamma), ca.cos(gamma)
        sp, cp = ca.sin(psi), ca.cos(psi)
        sl, cl = ca.sin(lat), ca.cos(lat)
        dh = v * sg
        dlon = v * cg * sp / (r * cl)
        dlat = v * cg * cp / r
        dv = -av.drag - g * sg
        dgamma = av.lift * ca.cos(bank) + (v**2 / r - g) * cg
        dpsi = av.lift * ca.sin(bank) / cg + v**2 / r * cg * sp * ca.tan(lat)
        if w != 0.0:
            dv += w**2 * r * cl * (sg * cl - cg * sl * cp)
            dgamma += 2.0 * w * v * cl * sp + w**2 * r * cl * (cg * cl + sg * cp * sl)
            dpsi += -2.0 * w * v * (ca.tan(gamma) * cp * cl - sl) + w**2 * r * sp * sl * cl / cg
        return [dh, dlon, dlat, dv, dgamma / v, dpsi / v]
