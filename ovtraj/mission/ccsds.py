"""A mission plan as CCSDS Orbit Data Messages: OEM (trajectory) and OPM (manoeuvres).

CCSDS 502.0-B-2, *Orbit Data Messages*, Blue Book, 2009, version 2.0 of both messages,
in KVN (keyword = value notation), so that GMAT, Orekit or STK load the plan:

* **OEM** (sec. 5): the whole planned trajectory from the insertion state to the
  terminal interface, as the plan's replay flies it (:func:`ovtraj.mission.fly.replay_ephemeris`:
  J2 orbital arcs, the deorbit descent, the open-loop guided entry). One segment per
  continuous arc: a new segment at every impulse (the velocity jumps), at the entry
  interface and at every bank reversal. Every segment declares its interpolation
  (``INTERPOLATION``, ``INTERPOLATION_DEGREE``, lowered where a segment has too few
  samples for the configured degree).
* **OPM** (sec. 3): the insertion state, the OV's mass, and the five impulses (two of
  the rendezvous, two of the transfer, the deorbit burn) as manoeuvres: ignition epoch,
  duration 0 (impulsive, as planned), the mass they burn (the rocket equation with the
  vehicle's specific impulse), and the delta-v in the declared frame.

Frame and time: the project's ECI is TEME (docs/conventions.md); every position,
velocity and delta-v is converted to EME2000 at its own epoch by the IAU-76/80
precession-nutation of :func:`ovtraj.astro.eme2000.teme_to_eme2000` (pyerfa). Epochs are
UTC, written as the plan's launch day plus seconds (leap seconds ignored, as everywhere
in the project). Positions in km, velocities in km/s, masses in kg (the standard's units).

The messages are a pure function of the plan and the settings: ``CREATION_DATE`` is the
plan's launch day (a comment says so), so the same plan exports byte-identical files.

Every text the settings or the plan put into a message (originator, object id, object
name, code version, segment and impulse names) is printable ASCII, as KVN requires
(CCSDS 502.0-B-3): a newline in one would write a header line of its own; anything else
is refused naming the field (:func:`ovtraj.config.export.kvn_value_problem`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.eme2000 import teme_to_eme2000
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.rocket import burn_durations
from ovtraj.config import scenario_from_dict
from ovtraj.config.export import FORMATS, CcsdsExportSettings, kvn_value_problem
from ovtraj.config.io_limits import echoed
from ovtraj.mission.ephemeris import EphemerisSegment
from ovtraj.mission.flight_report import FlightReport
from ovtraj.mission.fly import replay_ephemeris
from ovtraj.mission.plan import MissionPlan, PlanError
from ovtraj.store.files import StoreError, holds_other, writable_target, write_bytes
from ovtraj.units import S_PER_DAY

__all__ = ["FORMATS", "UnflownPlan", "export_plan", "oem_text", "opm_text"]


class UnflownPlan(PlanError):
    """The plan's replay does not reach its terminal interface: no trajectory to export."""


VERSION = "2.0"


def _epoch_text(day: Epoch, t_s: float) -> str:
    """CCSDS ASCII time (CCSDS 301.0-B-4 code A, UTC) with nanoseconds, no zone letter.

    Microseconds were not enough: a sample 9 s after the one before (a segment's short
    last interval), its epoch off by up to 0.5 us (4 mm along the track), put the
    reader's degree-7 Hermite interpolation 3-5 cm off mid-interval; with nanoseconds
    0.8 cm (tests/test_ccsds_export.py)."""
    return day.plus_seconds(t_s).iso(digits=9).removesuffix("Z")


def _julian_dates(day: Epoch, t_s: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Two-part UTC Julian dates of ``day + t_s`` (whole days first, as erfa takes them)."""
    whole, rest = np.divmod(np.asarray(t_s, dtype=float), S_PER_DAY)
    return day.jd1 + whole, day.jd2 + rest / S_PER_DAY


def _kvn(field: str, value: str) -> str:
    """``value``, if a KVN message can hold it (printable ASCII: a newline in it would
    write a header line of its own); :class:`PlanError` naming ``field`` otherwise."""
    problem = kvn_value_problem(value)
    if problem is not None:
        raise PlanError(f"{field} = {echoed(repr(value))}: {problem}")
    return value


def _header(kind: str, plan: MissionPlan, settings: CcsdsExportSettings) -> list[str]:
    design = plan.design
    code = _kvn("the plan's code_version", plan.code_version)
    return [
        f"CCSDS_{kind}_VERS = {VERSION}",
        f"COMMENT ovtraj mission plan, code {code}; design: parking "
        f"{design.parking_altitude_km:.3f} km, preparation {design.preparation_altitude_km:.3f} "
        f"km, separation delay {design.separation_delay_h:.4f} h",
        "COMMENT Converted from the project's TEME by IAU-76/80 precession-nutation (pyerfa); "
        "CREATION_DATE is the plan's launch day, so the same plan gives the same file",
        f"CREATION_DATE = {_epoch_text(plan.day, 0.0)}",
        f"ORIGINATOR = {_kvn('originator', settings.originator)}",
    ]


def _object(plan: MissionPlan, settings: CcsdsExportSettings) -> list[str]:
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    name = _kvn("the plan's vehicle.name", scenario.vehicle.name)
    return [
        f"OBJECT_NAME = {name}",
        f"OBJECT_ID = {_kvn('object_id', settings.object_id)}",
        "CENTER_NAME = EARTH",
        f"REF_FRAME = {settings.ref_frame}",
        f"TIME_SYSTEM = {settings.time_system}",
    ]


def _degree(samples: int, settings: CcsdsExportSettings) -> int:
    """The configured degree, or the highest the segment's samples support."""
    if settings.interpolation == "HERMITE":  # n samples with derivatives: degree 2n - 1
        return max(1, min(settings.interpolation_degree, 2 * samples - 1))
    return max(1, min(settings.interpolation_degree, samples - 1))


def oem_text(
    plan: MissionPlan, segments: Sequence[EphemerisSegment], settings: CcsdsExportSettings
) -> str:
    """The OEM (KVN) of ``segments`` (the replay's, in TEME): see the module notes."""
    if not segments:
        raise PlanError("the plan's replay produced no trajectory to export")
    day = plan.day
    lines = _header("OEM", plan, settings)
    for segment in segments:
        jd1, jd2 = _julian_dates(day, segment.t_s)
        r, v = teme_to_eme2000(jd1, jd2, segment.r_eci_m, segment.v_eci_mps)
        t0, t1 = float(segment.t_s[0]), float(segment.t_s[-1])
        lines += [
            "",
            "META_START",
            f"COMMENT {_kvn('segment name', segment.name)}",
            *_object(plan, settings),
            f"START_TIME = {_epoch_text(day, t0)}",
            f"STOP_TIME = {_epoch_text(day, t1)}",
            f"INTERPOLATION = {settings.interpolation}",
            f"INTERPOLATION_DEGREE = {_degree(len(segment.t_s), settings)}",
            "META_STOP",
            "",
        ]
        for t, position, velocity in zip(segment.t_s, r / 1e3, v / 1e3, strict=True):
            lines.append(
                f"{_epoch_text(day, float(t))} "
                + " ".join(f"{c:.6f}" for c in position)
                + " "
                + " ".join(f"{c:.9f}" for c in velocity)
            )
    return "\n".join(lines) + "\n"


def opm_text(plan: MissionPlan, settings: CcsdsExportSettings) -> str:
    """The OPM (KVN): the insertion state and the five impulses; see the module notes."""
    scenario = scenario_from_dict(plan.scenario, "the plan's scenario")
    vehicle = scenario.vehicle
    day = plan.day
    t_insertion = plan.launch.insertion_t_s
    jd1, jd2 = _julian_dates(day, np.array([t_insertion]))
    r, v = teme_to_eme2000(
        jd1,
        jd2,
        np.asarray([plan.launch.insertion_r_eci_m], dtype=float),
        np.asarray([plan.launch.insertion_v_eci_mps], dtype=float),
    )
    impulses = plan.impulses()
    dv = np.array([np.linalg.norm(burn.eci) for burn in impulses])
    exhaust_speed = vehicle.isp_s * scenario.earth.g0_m_s2
    _, masses = burn_durations(dv, vehicle.mass_kg, vehicle.thrust_n, exhaust_speed)
    burnt = masses * np.expm1(-dv / exhaust_speed)  # negative: the mass each impulse burns
    lines = [
        *_header("OPM", plan, settings),
        "",
        *_object(plan, settings),
        "",
        "COMMENT State vector: the insertion into the parking orbit",
        f"EPOCH = {_epoch_text(day, t_insertion)}",
        *(f"{key} = {value:.6f}" for key, value in zip(("X", "Y", "Z"), r[0] / 1e3, strict=True)),
        *(
            f"{key} = {value:.9f}"
            for key, value in zip(("X_DOT", "Y_DOT", "Z_DOT"), v[0] / 1e3, strict=True)
        ),
        "",
        "COMMENT Spacecraft parameters: the OV's wet mass in orbit (scenario vehicle.mass_kg)",
        f"MASS = {vehicle.mass_kg:.6f}",
    ]
    for burn, delta_mass in zip(impulses, burnt, strict=True):
        jd1, jd2 = _julian_dates(day, np.array([burn.t_s]))
        dv_eme, _ = teme_to_eme2000(jd1, jd2, burn.eci[None, :], np.zeros((1, 3)))
        lines += [
            "",
            f"COMMENT {_kvn('impulse name', burn.name)}: impulsive, "
            f"{float(np.linalg.norm(burn.eci)):.6f} m/s; mass "
            f"burnt by the rocket equation, Isp {vehicle.isp_s:g} s",
            f"MAN_EPOCH_IGNITION = {_epoch_text(day, burn.t_s)}",
            "MAN_DURATION = 0.000",
            f"MAN_DELTA_MASS = {delta_mass:.6f}",
            f"MAN_REF_FRAME = {settings.ref_frame}",
            *(f"MAN_DV_{k} = {value:.9f}" for k, value in enumerate(dv_eme[0] / 1e3, start=1)),
        ]
    return "\n".join(lines) + "\n"


def export_plan(
    plan: MissionPlan,
    fmt: str,
    out: Path,
    settings: CcsdsExportSettings,
    plan_id: str | None = None,
) -> tuple[Path, FlightReport | None]:
    """Write the plan's ``fmt`` (``"oem"`` or ``"opm"``) message to ``out``; ``plan_id``
    (the store's id of the plan, :func:`ovtraj.tracking.catalog_rows.plan_id`) is named in a
    ``COMMENT ovtraj plan <id>`` line, so that ``ovtraj lineage`` finds the plan again.

    Returns the path and, for the OEM, the replay that produced the trajectory. A file
    already at ``out`` with other content is never replaced (:class:`PlanError`); a
    replay that does not reach the terminal interface is refused with its reason.
    """
    if fmt not in FORMATS:
        raise PlanError(f"--format {fmt!r}: choose one of {', '.join(FORMATS)}")
    # the folder the user named is taken as it is (resolved); the file itself must be a
    # regular file or absent, checked before the replay
    out = Path(out)
    out = out.parent.resolve() / out.name
    try:
        writable_target(out)
    except StoreError as err:
        raise PlanError(f"--out {err}") from None
    report = None
    if fmt == "oem":
        report, segments = replay_ephemeris(
            plan, orbit_step_s=settings.orbit_step_s, entry_step_s=settings.entry_step_s
        )
        if not report.ok:
            raise UnflownPlan(f"the plan does not fly to its terminal interface: {report.reason}")
        text = oem_text(plan, segments, settings)
    else:
        text = opm_text(plan, settings)
    if plan_id is not None:
        first, rest = text.split("\n", 1)
        text = f"{first}\nCOMMENT ovtraj plan {plan_id}\n{rest}"
    payload = text.encode("ascii")
    try:
        if holds_other(out, payload):
            raise PlanError(f"{out}: another file is there; refusing to overwrite it")
        write_bytes(out, payload)
    except StoreError as err:
        raise PlanError(str(err)) from None
    return out, report
