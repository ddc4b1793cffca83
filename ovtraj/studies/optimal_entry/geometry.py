"""Downrange and cross-range on a spherical Earth, relative to the initial great circle.

The initial position ``p0`` and heading ``psi0`` (from north, clockwise) define the
initial great circle, with in-plane direction ``d0 = cos(psi0) n0 + sin(psi0) e0`` (north
and east unit vectors at ``p0``) and pole ``k = p0 x d0``. For a position ``p``:

* downrange angle ``atan2(p . d0, p . p0)``: the arc from ``p0`` to the foot of ``p`` on
  the initial great circle;
* cross-range angle ``asin(p . k)``: the arc from that circle, positive to the left of
  the initial heading.

Both are central angles [rad]; times the Earth radius they are ground distances (the
spherical-trigonometry projection of e.g. Vinh, Busemann & Culp, *Hypersonic and
Planetary Entry Flight Mechanics*, 1980, ch. 1). Written once for numpy and CasADi: the
caller passes the math functions.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

__all__ = ["GreatCircle"]


@dataclass(frozen=True)
class GreatCircle:
    """The initial great circle of a trajectory (angles in rad)."""

    longitude0: float
    latitude0: float
    heading0: float

    def _frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lon, lat, psi = self.longitude0, self.latitude0, self.heading0
        p0 = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
        east = np.array([-np.sin(lon), np.cos(lon), 0.0])
        north = np.array([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
        d0 = np.cos(psi) * north + np.sin(psi) * east
        return p0, d0, np.cross(p0, d0)

    def _angles(
        self, lon: Any, lat: Any, sin: Callable, cos: Callable, atan2: Callable, asin: Callable
    ) -> tuple[Any, Any]:
        p0, d0, k = self._frame()
        p = (cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat))
        along = sum(d0[i] * p[i] for i in range(3))
        radial = sum(p0[i] * p[i] for i in range(3))
        across = sum(k[i] * p[i] for i in range(3))
        return atan2(along, radial), asin(across)

    def angles(self, lon: Any, lat: Any) -> tuple[Any, Any]:
        """(downrange, cross-range) central angles [rad] of numpy longitudes/latitudes."""
        return self._angles(lon, lat, np.sin, np.cos, np.arctan2, np.arcsin)

    def angles_sx(self, lon: ca.SX, lat: ca.SX) -> tuple[ca.SX, ca.SX]:
        """The same for CasADi expressions."""
        return self._angles(lon, lat, ca.sin, ca.cos, ca.atan2, ca.asin)
