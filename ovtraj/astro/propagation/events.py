"""Events that stop or mark an orbit propagation.

Each event is a smooth function g(t, x) whose roots heyoka locates to machine
precision inside the integration step (no time grid). What is fixed when the
integrator is compiled is the *kind* of event, its direction and whether it is
terminal; the *value* (an altitude, a latitude...) is a runtime parameter, so one
compiled integrator serves every value.

Functions whose zero set has a spurious branch (sin(u - u0) also vanishes at
u0 + pi) carry an ``accepts`` check applied when a root is found.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np

Direction = Literal["any", "positive", "negative"]


@dataclass(frozen=True)
class EventContext:
    """What an event needs besides the state: the Earth model and its rotation."""

    radius_m: float
    earth_angle0_rad: float
    rotation_rate_rad_s: float


@dataclass(frozen=True)
class Event:
    """Base class; subclasses define the switching function.

    ``terminal`` is keyword-only so that the value of an event is its first
    positional argument: ``AltitudeCrossing(120e3)``.
    """

    terminal: bool = field(default=True, kw_only=True)
    kind: ClassVar[str] = "event"

    @property
    def direction(self) -> Direction:
        return "any"

    def signature(self) -> tuple[str, Direction, bool]:
        """What the compiled integrator depends on (values excluded)."""
        return (self.kind, self.direction, self.terminal)

    def parameters(self, ctx: EventContext) -> list[float]:
        raise NotImplementedError

    def expression(self, sv: dict[str, Any], par: list[Any], shared: dict[str, Any]) -> Any:
        raise NotImplementedError

    def accepts(self, t: float, state: np.ndarray, ctx: EventContext) -> bool:
        return True


@dataclass(frozen=True)
class AltitudeCrossing(Event):
    """|r| - R_E = altitude (spherical Earth). ``descending`` picks crossings downwards."""

    altitude_m: float = 0.0
    crossing: Literal["descending", "ascending", "any"] = "descending"
    kind: ClassVar[str] = "altitude"

    @property
    def direction(self) -> Direction:
        return {"descending": "negative", "ascending": "positive", "any": "any"}[self.crossing]

    def parameters(self, ctx: EventContext) -> list[float]:
        return [ctx.radius_m + self.altitude_m]

    def expression(self, sv: dict[str, Any], par: list[Any], shared: dict[str, Any]) -> Any:
        return shared["sqrt"](sv["x"] ** 2 + sv["y"] ** 2 + sv["z"] ** 2) - par[0]


@dataclass(frozen=True)
class ArgumentOfLatitudeCrossing(Event):
    """The osculating argument of latitude u passes ``u_rad`` (increasing).

    g = [r . (h x N)] / |h| cos u0 - (r . N) sin u0 = |N| r sin(u - u0), with
    N = z x h the node vector; undefined for equatorial orbits (N = 0).
    """

    u_rad: float = 0.0
    kind: ClassVar[str] = "argument_of_latitude"

    @property
    def direction(self) -> Direction:
        return "positive"

    def parameters(self, ctx: EventContext) -> list[float]:
        return [math.cos(self.u_rad), math.sin(self.u_rad)]

    def expression(self, sv: dict[str, Any], par: list[Any], shared: dict[str, Any]) -> Any:
        x, y, z, vx, vy, vz = (sv[k] for k in ("x", "y", "z", "vx", "vy", "vz"))
        hx, hy, hz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
        h = shared["sqrt"](hx * hx + hy * hy + hz * hz)
        r_dot_n = -x * hy + y * hx
        r_dot_h_cross_n = -hz * (x * hx + y * hy) + z * (hx * hx + hy * hy)
        return r_dot_h_cross_n / h * par[0] - r_dot_n * par[1]


@dataclass(frozen=True)
class LatitudeCrossing(Event):
    """Geocentric latitude of the sub-satellite point crosses ``latitude_rad``."""

    latitude_rad: float = 0.0
    crossing: Literal["northward", "southward", "any"] = "any"
    terminal: bool = field(default=False, kw_only=True)
    kind: ClassVar[str] = "latitude"

    @property
    def direction(self) -> Direction:
        return {"northward": "positive", "southward": "negative", "any": "any"}[self.crossing]

    def parameters(self, ctx: EventContext) -> list[float]:
        return [math.sin(self.latitude_rad)]

    def expression(self, sv: dict[str, Any], par: list[Any], shared: dict[str, Any]) -> Any:
        r = shared["sqrt"](sv["x"] ** 2 + sv["y"] ** 2 + sv["z"] ** 2)
        return sv["z"] / r - par[0]


@dataclass(frozen=True)
class LongitudeCrossing(Event):
    """Earth-fixed longitude of the sub-satellite point crosses ``longitude_rad``.

    With theta(t) = theta0 + omega t the Earth rotation angle and
    phi = theta(t) + lon0, g = y cos(phi) - x sin(phi) = rho sin(lon - lon0);
    the root at lon0 + pi is rejected by :meth:`accepts`.
    """

    longitude_rad: float = 0.0
    crossing: Literal["eastward", "westward", "any"] = "any"
    terminal: bool = field(default=False, kw_only=True)
    kind: ClassVar[str] = "longitude"

    @property
    def direction(self) -> Direction:
        return {"eastward": "positive", "westward": "negative", "any": "any"}[self.crossing]

    def parameters(self, ctx: EventContext) -> list[float]:
        return [ctx.earth_angle0_rad + self.longitude_rad]

    def expression(self, sv: dict[str, Any], par: list[Any], shared: dict[str, Any]) -> Any:
        phi = par[0] + shared["omega"] * shared["time"]
        return sv["y"] * shared["cos"](phi) - sv["x"] * shared["sin"](phi)

    def accepts(self, t: float, state: np.ndarray, ctx: EventContext) -> bool:
        phi = ctx.earth_angle0_rad + self.longitude_rad + ctx.rotation_rate_rad_s * t
        return state[0] * math.cos(phi) + state[1] * math.sin(phi) > 0.0
