"""Affine map between the physical design space and the unit cube [0, 1]^d.

Every surrogate of :mod:`ovtraj.surrogate` sees unit-cube inputs: the design variables
(altitudes in km, a delay in h) then have comparable scales, so one RBF basis scale
(``rbf_d0``) and the Kriging length scales' bounds fit all of them, and the classifiers'
kernels are isotropic in a meaningful sense (SMT and scikit-learn docs recommend scaled
inputs for both).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["SurrogateError", "UnitCube"]


class SurrogateError(ValueError):
    """Training data, bounds or a stored set that cannot be used (the text names the problem)."""


@dataclass(frozen=True, eq=False)
class UnitCube:
    """``u = (x - lower) / (upper - lower)``: the box [lower, upper] maps onto [0, 1]^d.

    Points outside the box map outside [0, 1]^d (no clipping): the surrogates then
    extrapolate, which the caller has to avoid or accept.
    """

    lower: np.ndarray = field()
    upper: np.ndarray = field()

    def __post_init__(self) -> None:
        lower = np.array(self.lower, dtype=float, copy=True).reshape(-1)
        upper = np.array(self.upper, dtype=float, copy=True).reshape(-1)
        if lower.size == 0 or lower.shape != upper.shape:
            raise SurrogateError(
                f"bounds: lower has {lower.size} values and upper {upper.size}; "
                "they need one value per input (at least one)"
            )
        if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
            raise SurrogateError("bounds: lower and upper must be finite numbers")
        bad = np.flatnonzero(lower >= upper)
        if bad.size:
            pairs = ", ".join(f"input {i}: [{lower[i]:g}, {upper[i]:g}]" for i in bad)
            raise SurrogateError(f"bounds: lower must be < upper for every input ({pairs})")
        lower.flags.writeable = False
        upper.flags.writeable = False
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)

    @property
    def dim(self) -> int:
        return int(self.lower.size)

    def _check(self, x: np.ndarray, what: str) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.ndim != 2 or x.shape[1] != self.dim:
            raise SurrogateError(
                f"{what}: expected an array of shape (m, {self.dim}), got {x.shape}"
            )
        return x

    def to_unit(self, x: np.ndarray) -> np.ndarray:
        """Physical points (m, d) -> unit-cube points (m, d)."""
        x = self._check(x, "to_unit")
        return (x - self.lower) / (self.upper - self.lower)

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """Unit-cube points (m, d) -> physical points (m, d)."""
        u = self._check(u, "from_unit")
        return self.lower + u * (self.upper - self.lower)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, UnitCube):
            return NotImplemented
        return bool(
            np.array_equal(self.lower, other.lower) and np.array_equal(self.upper, other.upper)
        )

    def __hash__(self) -> int:
        return hash((self.lower.tobytes(), self.upper.tobytes()))
