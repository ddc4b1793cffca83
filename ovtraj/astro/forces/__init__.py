"""The high-fidelity force model's terms as heyoka expressions.

The terms are declared once in :mod:`.terms` (name, switch, needs). One module per
term, each a public function of symbolic positions, velocities and time that returns
expressions: the Earth's field to degree and order n (:mod:`.gravity_field`),
thermospheric drag (:mod:`.drag`), the Sun and the Moon as point masses
(:mod:`.third_body`), cannonball radiation pressure with the Earth's shadow
(:mod:`.radiation_pressure`); the time scales (:mod:`.time_scales`) and the Earth
orientation and space-weather data (:mod:`.earth_data`) they are evaluated with. The
equations are integrated by :mod:`.propagator`. The terms are assembled from the
settings (``configs/force_model.yaml``) in :mod:`ovtraj.mission.high_fidelity`.

Frames: the state is in the project's ECI, SGP4's TEME of date (``docs/conventions.md``).
The Earth-fixed frame is the ITRS, reached by heyoka's TEME -> ITRS rotation (GMST-82 of
UT1 and polar motion from the IERS EOP, Vallado et al. 2006); the Sun and Moon come from
the ICRS by the IAU 2006/2000A precession-nutation (heyoka's ICRS -> ITRS) and back.
Units: m, m/s, s, kg; time ``t`` in s from the arc's origin epoch.
"""
