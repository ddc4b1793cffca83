"""CCSDS export of a mission plan: OEM and OPM read back by independent readers.

* The OEM is read by the ``oem`` package (Brad Sease, MIT; it enforces the OEM's
  mandatory keywords and interpolates with the declared method), so a mistake in a
  keyword or the declared interpolation fails here, not in the analyst's tool.
* The OPM is read by ``ccsds-ndm`` (E. Imre; the CCSDS NDM XML schemas as typed models).
* The frame transform itself is checked against a published example and an
  independent implementation in ``tests/test_eme2000.py``.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from ovtraj.astro.eme2000 import eme2000_to_teme, teme_to_eme2000
from ovtraj.cli import app
from ovtraj.config.base import ConfigError, model_from_dict
from ovtraj.config.export import CcsdsExportSettings, default_export_settings
from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission.ccsds import export_plan, oem_text, opm_text
from ovtraj.mission.chain import MissionContext, MissionDesign
from ovtraj.mission.fly import replay_ephemeris
from ovtraj.mission.plan import MissionPlan, PlanError
from ovtraj.mission.plan_build import build_plan
from ovtraj.mission.plan_store import write_plan
from ovtraj.paths import config_path
from ovtraj.target_sources import load_scenario

FEASIBLE = MissionDesign(285.06, 326.96, 0.79)
runner = CliRunner()


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(config_path("scenario.yaml"))


@pytest.fixture(scope="module")
def plan(scenario, tmp_path_factory):
    context = MissionContext(scenario, find_launch_fit(scenario))
    cache = tmp_path_factory.mktemp("launch_solves")
    return build_plan(
        context, FEASIBLE, source={"run_id": "test", "front_index": 0}, launch_cache=cache
    )


@pytest.fixture(scope="module")
def plan_file(plan, tmp_path_factory):
    json_path, _ = write_plan(plan, tmp_path_factory.mktemp("plan"), "chosen")
    return json_path


@pytest.fixture(scope="module")
def settings():
    return default_export_settings()


@pytest.fixture(scope="module")
def replay(plan, settings):
    return replay_ephemeris(
        plan, orbit_step_s=settings.orbit_step_s, entry_step_s=settings.entry_step_s
    )


@pytest.fixture(scope="module")
def oem_file(plan_file, tmp_path_factory):
    out = tmp_path_factory.mktemp("oem") / "plan.oem"
    result = runner.invoke(app, ["export", str(plan_file), "--format", "oem", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == f"oem: {out.resolve()}"
    return out


def _seconds(epoch, plan: MissionPlan) -> float:
    """Seconds of an astropy UTC ``Time`` from the plan's launch day (no leap second in 2026-12)."""
    day = plan.day
    return float((epoch.jd1 - day.jd1) + (epoch.jd2 - day.jd2)) * 86400.0


def test_oem_reads_back_with_its_metadata_and_the_replayed_states(oem_file, plan, replay, scenario):
    from oem import OrbitEphemerisMessage

    report, segments = replay
    message = OrbitEphemerisMessage.open(oem_file)
    assert message.version == "2.0"
    read = message.segments
    # The ascent's phases, 5 impulses, the entry interface, the bank reversals.
    assert len(read) == len(segments) >= 13
    assert [s.name for s in segments[:6]] == [
        "ascent: free fall",
        "ascent: stage 1 burn",
        "ascent: separation coast",
        "ascent: stage 2 burn",
        "ascent: coast",
        "ascent: stage 3 burn",
    ]
    scenario_vehicle = plan.scenario["vehicle"]["name"]
    for segment, ours in zip(read, segments, strict=True):
        meta = segment.metadata
        assert meta["REF_FRAME"] == "EME2000" and meta["TIME_SYSTEM"] == "UTC"
        assert meta["CENTER_NAME"] == "EARTH" and meta["OBJECT_NAME"] == scenario_vehicle
        assert meta["INTERPOLATION"] == "HERMITE"
        states = list(segment.states)
        assert len(states) == len(ours.t_s)
        times = np.array([_seconds(s.epoch, plan) for s in states])
        np.testing.assert_allclose(times, ours.t_s, rtol=0, atol=2e-6)
        # The file's EME2000 states, back in TEME by the inverse rotation, are the replay's
        # to the file's digits (1e-6 km and 1e-9 km/s per component).
        r = np.array([s.position for s in states]) * 1e3
        v = np.array([s.velocity for s in states]) * 1e3
        jd1, jd2 = np.full(len(times), plan.day.jd1), plan.day.jd2 + ours.t_s / 86400.0
        r_teme, v_teme = eme2000_to_teme(jd1, jd2, r, v)
        assert np.max(np.abs(r_teme - ours.r_eci_m)) < 1e-3
        assert np.max(np.abs(v_teme - ours.v_eci_mps)) < 1e-6
    first, last = next(iter(read[0].states)), list(read[-1].states)[-1]
    assert _seconds(first.epoch, plan) == pytest.approx(plan.launch.drop_t_s, abs=2e-6)
    assert _seconds(last.epoch, plan) == pytest.approx(report.terminal["t_s"], abs=2e-6)
    # The last state is the replay's terminal point: its altitude over the sphere.
    altitude = np.linalg.norm(last.position) * 1e3 - scenario.earth.radius
    assert altitude == pytest.approx(report.terminal["altitude_m"], abs=1.0)


def test_the_declared_interpolation_reproduces_the_trajectory_between_samples(
    oem_file, plan, settings, scenario
):
    """The reader's Hermite interpolation of the 60 s / 2 s file at the middle of every
    sample interval, against: on the orbital arcs (equal intervals of at most 60 s), the
    file's own state before it propagated there by an independent DOP853 (point mass + J2,
    rtol 1e-12; the file's 1 mm / 1 mm/s digits add <= 1 mm over 30 s); in the atmosphere,
    the replay flown again at half the step."""
    from astropy.time import TimeDelta
    from oem import OrbitEphemerisMessage

    from ovtraj.astro.propagation.reference import propagate_dop853

    earth = scenario.earth
    message = OrbitEphemerisMessage.open(oem_file)
    _, fine = replay_ephemeris(
        plan, orbit_step_s=settings.orbit_step_s / 2, entry_step_s=settings.entry_step_s / 2
    )
    worst_position, worst_velocity = {}, {}
    shortest_orbit_interval = np.inf
    for segment, dense in zip(message.segments, fine, strict=True):
        states = list(segment.states)
        epochs = [s.epoch for s in states]
        # The ascent's segments hold the launch integrator's own RK4 step points: there is
        # no finer flight of the same discretisation to compare with between them.
        if len(epochs) < 4 or dense.name.startswith("ascent:"):
            continue
        kind = "entry" if dense.name.startswith("entry,") else "orbit"
        if kind == "orbit":
            t = np.array([_seconds(e, plan) for e in epochs])
            shortest_orbit_interval = min(shortest_orbit_interval, float(np.min(np.diff(t))))
            middle = 0.5 * (t[:-1] + t[1:])
            jd1, jd2 = plan.day.jd1 + 0 * t[:-1], plan.day.jd2 + t[:-1] / 86400.0
            r0, v0 = eme2000_to_teme(
                jd1,
                jd2,
                np.array([s.position for s in states[:-1]]) * 1e3,
                np.array([s.velocity for s in states[:-1]]) * 1e3,
            )
            flown = np.array(
                [
                    propagate_dop853(
                        np.r_[r, v],
                        a,
                        b,
                        mu=earth.mu,
                        radius=earth.radius,
                        j2=earth.j2,
                        rtol=1e-12,
                        atol=1e-9,
                    )
                    for r, v, a, b in zip(r0, v0, t[:-1], middle, strict=True)
                ]
            )
            r_teme, v_teme = flown[:, :3], flown[:, 3:]
        else:
            middle = dense.t_s[1:-1:2][: len(epochs) - 1]
            r_teme = dense.r_eci_m[1:-1:2][: len(middle)]
            v_teme = dense.v_eci_mps[1:-1:2][: len(middle)]
        jd1, jd2 = plan.day.jd1 + 0 * middle, plan.day.jd2 + middle / 86400.0
        r_true, v_true = teme_to_eme2000(jd1, jd2, r_teme, v_teme)
        for t_mid, r, v in zip(middle, r_true, v_true, strict=True):
            state = segment(epochs[0] + TimeDelta(t_mid - _seconds(epochs[0], plan), format="sec"))
            worst_position[kind] = max(
                worst_position.get(kind, 0.0), float(np.linalg.norm(state.position * 1e3 - r))
            )
            worst_velocity[kind] = max(
                worst_velocity.get(kind, 0.0), float(np.linalg.norm(state.velocity * 1e3 - v))
            )
    assert set(worst_position) == {"orbit", "entry"}
    # Equal intervals per orbital arc: none much shorter than the step (a 2.3 s last
    # interval beside 60 s ones cost 0.33 m mid-interval before, docs/export.md).
    assert shortest_orbit_interval > 0.5 * settings.orbit_step_s
    # Measured (docs/export.md): orbit arcs (Hermite degree 7, <= 60 s) a few mm and
    # ~1e-4 m/s at worst; entry (2 s) 2.3-18 mm/s over 13 plans whose H_P0 differed by
    # 1e-8 to 1e-3 km (1.2-4.9 mm over 6 of them): the entry's worst point jumps along the
    # flight from one to the next.
    assert worst_position["orbit"] < 0.05 and worst_velocity["orbit"] < 5e-4
    assert worst_position["entry"] < 0.01 and worst_velocity["entry"] < 0.05


def test_opm_reads_back_with_the_five_impulses_and_the_rocket_equation(
    plan_file, plan, scenario, tmp_path
):
    from ccsds_ndm.ndm_io import NdmIo

    out = tmp_path / "plan.opm"
    result = runner.invoke(
        app, ["export", str(plan_file), "--format", "opm", "--out", str(out), "--json"]
    )
    assert result.exit_code == 0, result.output
    row = json.loads(result.stdout)
    assert row["path"] == str(out.resolve()) and row["format"] == "opm"
    opm = NdmIo().from_path(out)
    assert opm.version == "2.0"
    meta = opm.body.segment.metadata
    assert (meta.ref_frame, meta.time_system, meta.center_name) == ("EME2000", "UTC", "EARTH")
    data = opm.body.segment.data
    state = data.state_vector
    r = np.array([state.x.value, state.y.value, state.z.value]) * 1e3
    assert np.linalg.norm(r) == pytest.approx(
        np.linalg.norm(plan.launch.insertion_r_eci_m), abs=1e-3
    )
    burns = data.maneuver_parameters
    planned = plan.impulses()
    assert len(burns) == len(planned) == 5
    mass = data.spacecraft_parameters.mass.value
    vehicle = plan.scenario["vehicle"]
    assert mass == pytest.approx(vehicle["mass_kg"])
    exhaust = vehicle["isp_s"] * scenario.earth.g0_m_s2
    for burn, ours in zip(burns, planned, strict=True):
        assert burn.man_ref_frame == "EME2000" and burn.man_duration.value == 0.0
        dv = np.array([burn.man_dv_1.value, burn.man_dv_2.value, burn.man_dv_3.value]) * 1e3
        assert np.linalg.norm(dv) == pytest.approx(np.linalg.norm(ours.eci), abs=1e-6)
        # The delta-v is the planned one rotated into EME2000 at the burn's own epoch (to
        # the file's 1e-9 km/s digits); the rotation since J2000 is under 0.5 deg.
        seconds = np.array([ours.t_s])
        expected, _ = teme_to_eme2000(
            plan.day.jd1 + np.floor(seconds / 86400.0),
            plan.day.jd2 + np.mod(seconds, 86400.0) / 86400.0,
            ours.eci[None, :],
            np.zeros((1, 3)),
        )
        assert np.max(np.abs(dv - expected[0])) < 1e-6
        angle = math.degrees(
            math.acos(np.dot(dv, ours.eci) / (np.linalg.norm(dv) * np.linalg.norm(ours.eci)))
        )
        assert 0.0 < angle < 0.5
        assert burn.man_delta_mass.value < 0.0
    # Sequential masses burnt sum to the rocket equation on the total delta-v.
    total_dv = sum(float(np.linalg.norm(b.eci)) for b in planned)
    burnt = -sum(b.man_delta_mass.value for b in burns)
    assert burnt == pytest.approx(mass * -math.expm1(-total_dv / exhaust), abs=1e-5)


def test_same_plan_same_bytes_and_no_overwrite(plan, settings, replay, tmp_path):
    _, segments = replay
    assert oem_text(plan, segments, settings) == oem_text(plan, segments, settings)
    out = tmp_path / "m.opm"
    path, _ = export_plan(plan, "opm", out, settings)
    before = path.read_bytes()
    export_plan(plan, "opm", out, settings)  # the same content: accepted as stored
    assert path.read_bytes() == before == opm_text(plan, settings).encode("ascii")
    other = tmp_path / "other.opm"
    other.write_text("someone else's file\n")
    with pytest.raises(PlanError, match="refusing to overwrite"):
        export_plan(plan, "opm", other, settings)
    assert other.read_text() == "someone else's file\n"


def test_export_faults_are_one_line_with_their_exit_code(plan, plan_file, tmp_path):
    bad_format = runner.invoke(
        app, ["export", str(plan_file), "--format", "sp3", "--out", str(tmp_path / "x")]
    )
    assert bad_format.exit_code == 2 and "'--format'" in bad_format.output
    assert "'sp3' is not one of 'oem', 'opm'" in bad_format.output
    missing = runner.invoke(
        app,
        ["export", str(tmp_path / "none.json"), "--format", "oem", "--out", str(tmp_path / "y")],
    )
    assert missing.exit_code == 2 and "none.json" in missing.output
    settings = tmp_path / "export.yaml"
    settings.write_text(
        (config_path("ccsds_export.yaml"))
        .read_text()
        .replace("orbit_step_s: 60.0", "orbit_step_s: -1")
    )
    bad_settings = runner.invoke(
        app,
        [
            "export",
            str(plan_file),
            "--format",
            "oem",
            "--out",
            str(tmp_path / "z"),
            "--settings",
            str(settings),
        ],
    )
    assert bad_settings.exit_code == 2 and "orbit_step_s" in bad_settings.output
    data = plan.to_dict()
    data["deorbit"]["burn"]["dv_eci_mps"] = [0.0, 0.0, 0.0]  # never comes down
    unflown, _ = write_plan(MissionPlan.model_validate(data), tmp_path, "unflown")
    result = runner.invoke(
        app, ["export", str(unflown), "--format", "oem", "--out", str(tmp_path / "u.oem")]
    )
    assert result.exit_code == 1 and "entry interface" in result.output
    assert not (tmp_path / "u.oem").exists() and not (tmp_path / "x").exists()


def test_control_characters_never_reach_a_message_header(plan, plan_file, settings, tmp_path):
    """A newline in the originator wrote a header line of its own (``OBJECT_NAME =
    FORGED`` after ``ORIGINATOR``). Every text written into a message is
    printable ASCII (CCSDS 502.0-B-3, KVN) or refused naming its field, nothing written."""
    forged = tmp_path / "export.yaml"
    forged.write_text(
        config_path("ccsds_export.yaml")
        .read_text()
        .replace("originator: OVTRAJ", 'originator: "OVTRAJ\\nOBJECT_NAME = FORGED"')
    )
    out = tmp_path / "forged.opm"
    args = ["export", str(plan_file), "--format", "opm", "--out", str(out)]
    result = runner.invoke(app, [*args, "--settings", str(forged)])
    assert result.exit_code == 2 and result.stdout == ""
    assert result.stderr.splitlines() == [
        f"invalid configuration in {forged}: originator = 'OVTRAJ\\nOBJECT_NAME = FORGED': "
        "character '\\n' at position 6: a CCSDS KVN value holds printable ASCII only "
        "(codes 32-126, CCSDS 502.0-B-3)"
    ]
    assert not out.exists()
    non_ascii = {**settings.model_dump(), "object_id": "OV-\u00e9t\u00e9"}
    with pytest.raises(ConfigError, match="object_id = 'OV-\u00e9t\u00e9': character '\u00e9'"):
        model_from_dict(CcsdsExportSettings, non_ascii, "test")
    # from the plan file: the vehicle's name and an impulse's name
    data = plan.to_dict()
    data["scenario"]["vehicle"]["name"] = "OV\nOBJECT_ID = X"
    with pytest.raises(PlanError, match=r"^the plan's vehicle\.name = 'OV\\nOBJECT_ID = X': "):
        export_plan(MissionPlan.model_validate(data), "opm", out, settings)
    data = plan.to_dict()
    data["deorbit"]["burn"]["name"] = "deorbit\x1b[2J"
    with pytest.raises(PlanError, match=r"^impulse name = 'deorbit\\x1b\[2J': character '\\x1b'"):
        export_plan(MissionPlan.model_validate(data), "opm", out, settings)
    assert not out.exists()
