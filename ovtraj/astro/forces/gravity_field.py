"""The Earth's gravity field: EGM2008 spherical harmonics in the Earth-fixed frame.

a_TEME = R_ITRS->TEME(t) grad U_EGM2008(R_TEME->ITRS(t) r), with U the fully normalised
spherical-harmonic potential to degree n and order m (Pavlis, Holmes, Kenyon & Factor,
"The development and evaluation of the Earth Gravitational Model 2008", JGR 117, 2012;
its own GM = 3.986004415e14 m^3/s^2 and a = 6378136.3 m), evaluated by heyoka's
``egm2008_acc`` (Cunningham's recursion; Montenbruck & Gill 2000 sec. 3.2.4). The frame
rotation is heyoka's TEME <-> ITRS (GMST-82 of UT1 and polar motion, Vallado et al.
2006), the degree-0 term included: this is the whole field, not a perturbation.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import heyoka as hy

__all__ = ["egm2008_acceleration", "teme_to_itrs"]


def teme_to_itrs(r_teme: Sequence[Any], tt: Any, eop: hy.eop_data) -> list[Any]:
    """Earth-fixed (ITRS) components of a TEME vector at TT centuries ``tt``."""
    return list(hy.model.rot_teme_itrs(list(r_teme), tt, eop))


def egm2008_acceleration(
    r_teme: Sequence[Any], tt: Any, *, degree: int, order: int, eop: hy.eop_data
) -> list[Any]:
    """EGM2008 acceleration [m/s^2] in TEME at the TEME position ``r_teme`` [m]."""
    r_itrs = teme_to_itrs(r_teme, tt, eop)
    a_itrs = hy.model.egm2008_acc(r_itrs, degree, order)
    return list(hy.model.rot_itrs_teme(a_itrs, tt, eop))
