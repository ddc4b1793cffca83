"""The plan's HTML report shows what an analyst expects, as a browser renders it.

The report is the one ``ovtraj pipeline`` wrote for the last of the session's re-plan
nights (tests/conftest.py:replan_nights: a short pipeline run by the command into a
store). Headless chromium opens the file and answers over its DevTools protocol (CDP,
a websocket on a free port of 127.0.0.1; the browser started the way
tests/test_prefect_ui.py starts it, its own profile, stopped by its process group): every
expected figure is on the page by its alt text, every ``<img>`` has loaded (its decoded
PNG is wider than 0 pixels), and the limit-margin and manoeuvre tables hold the plan's
figures. Skipped only when ``chromium`` is not installed (``.ci/run`` installs it).

The tables are also checked against independent figures: the propellant of each burn by
the rocket equation computed here from the Isp and g0 of ``configs/``, the RTN components'
magnitude against the stored dV, every margin as the limit minus the peak, the limits read
from the plan's own scenario; a flight of the plan (the J2 replay and the
``--fidelity high`` closed loops, flown here) beside the plan's figures.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
import yaml

from ovtraj.config import scenario_from_dict
from ovtraj.mission.manoeuvres import manoeuvre_table, propellant_budget
from ovtraj.mission.margins import limit_margins, margins_frame
from ovtraj.mission.plan import MissionPlan
from ovtraj.mission.plan_store import read_plan
from ovtraj.pipeline.report import ASCENT_ALT, ENTRY_ALT
from tests.conftest import REPO, replan_nights
from tests.test_deployments import _stop

# minutes: the session's re-plan nights (shared), then flights
pytestmark = pytest.mark.slow

CHROMIUM = shutil.which("chromium")
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="no chromium on PATH (.ci/run installs it: apt-get install chromium)"
)
START_TIMEOUT_S = 30.0  # until chromium writes its DevTools port
PAGE_TIMEOUT_S = 60.0  # until the report's load event
MISSION_FIGURES = ("_profile.png", "_ground_track.png", "_reentry_corridor.png", "-front.png")

# Run in the page once it has loaded: every image, and every table with its section heading.
PAGE_CONTENT = """JSON.stringify({
  images: [...document.images].map(i => ({
    alt: i.alt, complete: i.complete, width: i.naturalWidth, height: i.naturalHeight,
    caption: i.closest('figure')?.querySelector('figcaption')?.textContent ?? null})),
  tables: [...document.querySelectorAll('table')].map(t => {
    let h = t.previousElementSibling;
    while (h && h.tagName !== 'H2') h = h.previousElementSibling;
    return {heading: h ? h.textContent : null,
            rows: [...t.rows].map(r => [...r.cells].map(c => c.textContent))};
  }),
})"""


@pytest.fixture(scope="module")
def nights(tmp_path_factory) -> dict[str, Any]:
    return replan_nights(tmp_path_factory)


@pytest.fixture(scope="module")
def plan_json(nights) -> Path:
    return nights["plans"][-1]


@pytest.fixture(scope="module")
def plan(plan_json) -> MissionPlan:
    return read_plan(plan_json)


@pytest.fixture(scope="module")
def scenario(plan):
    return scenario_from_dict(plan.scenario, "the plan's scenario")


@pytest.fixture(scope="module")
def report(plan_json) -> Path:
    path = plan_json.with_name(f"{plan_json.stem}-report.html")
    assert path.is_file(), f"ovtraj pipeline wrote no report beside {plan_json}"
    return path


class _Page:
    """One page of a DevTools websocket: numbered commands, events kept aside."""

    def __init__(self, socket: Any) -> None:
        self.socket = socket
        self.events: list[dict[str, Any]] = []
        self.next_id = 0

    def send(self, method: str, **params: Any) -> dict[str, Any]:
        self.next_id += 1
        self.socket.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        deadline = time.monotonic() + PAGE_TIMEOUT_S
        while True:
            message = json.loads(self.socket.recv(timeout=max(deadline - time.monotonic(), 0.1)))
            if message.get("id") == self.next_id:
                assert "error" not in message, f"{method}: {message['error']}"
                return message.get("result", {})
            self.events.append(message)

    def wait_for(self, event: str) -> None:
        deadline = time.monotonic() + PAGE_TIMEOUT_S
        while not any(e.get("method") == event for e in self.events):
            remaining = deadline - time.monotonic()
            assert remaining > 0, f"no {event} within {PAGE_TIMEOUT_S:.0f} s"
            self.events.append(json.loads(self.socket.recv(timeout=remaining)))


def rendered(url: str, profile: Path) -> dict[str, Any]:
    """``url`` loaded in headless chromium; :data:`PAGE_CONTENT` evaluated in it."""
    from websockets.sync.client import connect

    profile.mkdir(parents=True, exist_ok=True)
    command = [
        str(CHROMIUM),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",  # a container's small /dev/shm
        f"--user-data-dir={profile}",
        "--remote-debugging-address=127.0.0.1",
        "--remote-debugging-port=0",  # a free port, written to DevToolsActivePort
        "about:blank",
    ]
    log = (profile / "chromium.log").open("w")
    process = subprocess.Popen(
        command, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
    )
    try:
        port_file = profile / "DevToolsActivePort"
        started = time.monotonic()
        while not (port_file.is_file() and port_file.read_text().strip()):
            assert process.poll() is None, f"chromium exited {process.returncode}"
            assert time.monotonic() - started < START_TIMEOUT_S, "chromium gave no DevTools port"
            time.sleep(0.1)
        port = int(port_file.read_text().splitlines()[0])
        target = httpx.put(f"http://127.0.0.1:{port}/json/new?about:blank", timeout=10).json()
        with connect(target["webSocketDebuggerUrl"], max_size=2**24) as socket:
            page = _Page(socket)
            page.send("Page.enable")
            page.send("Page.navigate", url=url)
            page.wait_for("Page.loadEventFired")
            answer = page.send("Runtime.evaluate", expression=PAGE_CONTENT, returnByValue=True)
        return json.loads(answer["result"]["value"])
    finally:
        _stop(process, signal.SIGTERM, timeout_s=10)  # and whatever it left in its group
        log.close()


@pytest.fixture(scope="module")
def page(report, tmp_path_factory) -> dict[str, Any]:
    return rendered(report.as_uri(), tmp_path_factory.mktemp("chromium-profile"))


def _table(page: dict[str, Any], heading: str) -> list[dict[str, str]]:
    """The rows of the table under ``heading`` as {column: cell}."""
    found = [t["rows"] for t in page["tables"] if t["heading"] == heading]
    assert found, f"no table under {heading!r}: {[t['heading'] for t in page['tables']]}"
    head, *rows = found[0]
    return [dict(zip(head, row, strict=True)) for row in rows]


@needs_chromium
def test_every_expected_figure_is_on_the_page_and_has_loaded(page, plan_json):
    images = page["images"]
    alts = [image["alt"] for image in images]
    expected = [ASCENT_ALT, ENTRY_ALT, "front.png"]
    expected += [f"{plan_json.stem}{suffix}" for suffix in MISSION_FIGURES]
    for alt in expected:
        assert alt in alts, f"no figure {alt!r} on the page: {alts}"
    captions = {image["alt"]: image["caption"] or "" for image in images}
    assert f"{plan_json.stem}_ascent.png" in captions[ASCENT_ALT]
    assert f"{plan_json.stem}_entry_histories.png" in captions[ENTRY_ALT]
    for image in images:
        assert image["complete"] and image["width"] > 0 and image["height"] > 0, image


@needs_chromium
def test_the_page_holds_each_margin_as_the_limit_minus_the_peak(page, plan):
    rows = _table(page, "Path peaks against their limits")
    limits = plan.scenario["reentry"]["limits"]
    launcher = plan.scenario["launch"]["launcher"]["limits"]
    reentry = plan.reentry
    expected = {  # peak, limit: the plan's stored peak, its scenario's limit
        "entry peak heat rate": (reentry.max_heat_rate_w_m2 / 1e3, limits["max_heat_rate_kw_m2"]),
        "entry peak load factor": (reentry.max_load_g, limits["max_load_g"]),
        "entry peak dynamic pressure": (
            reentry.max_dynamic_pressure_pa / 1e3,
            limits["max_dynamic_pressure_kpa"],
        ),
        "entry peak bank angle": (reentry.max_bank_deg, limits["max_bank_deg"]),
        "ascent peak dynamic pressure": (
            plan.launch.max_dynamic_pressure_pa / 1e3,
            launcher["max_dynamic_pressure_kpa"],
        ),
        "ascent peak axial load": (plan.launch.max_axial_load_g, launcher["max_axial_load_g"]),
    }
    shown = {row["quantity"]: row for row in rows}
    for quantity, (peak, limit) in expected.items():
        row = shown[quantity]
        assert float(row["peak"]) == pytest.approx(peak, rel=1e-4), quantity
        assert float(row["limit"]) == pytest.approx(limit, rel=1e-9), quantity
        assert float(row["margin"]) == pytest.approx(limit - peak, rel=1e-3, abs=1e-3), quantity
        percent = 100.0 * (limit - peak) / limit
        assert float(row["margin [%]"]) == pytest.approx(percent, abs=0.051), quantity
    largest = max(plan.impulses(), key=lambda burn: burn.dv_mps)
    row = shown[f"largest single impulse ({largest.name})"]
    limit = plan.scenario["vehicle"]["max_impulse_mps"]
    assert float(row["margin"]) == pytest.approx(limit - largest.dv_mps, rel=1e-3)


@needs_chromium
def test_the_page_lists_every_burn_with_its_rtn_components(page, plan):
    rows = _table(page, "Manoeuvres")
    burns = plan.impulses()
    assert [row["manoeuvre"] for row in rows] == [burn.name for burn in burns]
    for row, burn in zip(rows, burns, strict=True):
        assert float(row["|dV| [m/s]"]) == pytest.approx(burn.dv_mps, abs=5e-4)
        assert float(row["dV radial R [m/s]"]) == pytest.approx(burn.dv_radial_mps, abs=5e-4)
        assert float(row["dV along-track T [m/s]"]) == pytest.approx(
            burn.dv_along_track_mps, abs=5e-4
        )
        assert float(row["dV cross-track N [m/s]"]) == pytest.approx(
            burn.dv_cross_track_mps, abs=5e-4
        )
        assert burn.epoch_utc[:19] in row["epoch (UTC)"]
        assert float(row["propellant [kg]"]) > 0.0 and float(row["duration [s]"]) > 0.0


def test_propellant_and_duration_follow_the_rocket_equation_with_the_configured_isp(plan, scenario):
    """By hand: each burn from the mass the earlier ones left, the exhaust speed the Isp
    of configs/scenario.yaml times the g0 of configs/earth.yaml."""
    vehicle = yaml.safe_load((REPO / "configs" / "scenario.yaml").read_text())["vehicle"]
    g0 = yaml.safe_load((REPO / "configs" / "earth.yaml").read_text())["g0_m_s2"]
    assert plan.scenario["vehicle"] == vehicle  # the plan flies the shipped OV
    c = vehicle["isp_s"] * g0
    table = manoeuvre_table(plan, scenario)
    mass = vehicle["mass_kg"]
    for row, burn in zip(table.itertuples(), plan.impulses(), strict=True):
        burnt = mass * (1.0 - math.exp(-burn.dv_mps / c))
        assert row.mass_before_kg == pytest.approx(mass, rel=1e-12)
        assert row.propellant_kg == pytest.approx(burnt, rel=1e-10)
        # constant thrust: the propellant flows at F / c for the whole burn
        assert row.duration_s == pytest.approx(burnt * c / vehicle["thrust_n"], rel=1e-10)
        mass -= burnt
    total_dv = sum(burn.dv_mps for burn in plan.impulses())
    used = vehicle["mass_kg"] * (1.0 - math.exp(-total_dv / c))
    budget = propellant_budget(table, scenario)
    assert budget.used_kg == pytest.approx(used, rel=1e-10)
    assert budget.loaded_kg == vehicle["mass_kg"] - vehicle["dry_mass_kg"]


def test_rtn_components_make_the_stored_dv(plan, scenario):
    table = manoeuvre_table(plan, scenario)
    rtn = table[["dv_radial_mps", "dv_along_track_mps", "dv_cross_track_mps"]].to_numpy()
    eci = np.array([burn.dv_eci_mps for burn in plan.impulses()])
    np.testing.assert_allclose(np.linalg.norm(rtn, axis=1), table["dv_mps"], rtol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(eci, axis=1), table["dv_mps"], rtol=1e-9)


def test_margins_are_the_limits_minus_the_peaks(plan, scenario):
    frame = margins_frame(limit_margins(plan, scenario))
    np.testing.assert_allclose(frame["margin"], frame["limit"] - frame["peak"], rtol=0, atol=0)
    np.testing.assert_allclose(
        frame["margin_percent"], 100.0 * (frame["limit"] - frame["peak"]) / frame["limit"]
    )
    limits = plan.scenario["reentry"]["limits"]
    shown = frame.set_index("quantity")
    assert shown.loc["entry peak load factor", "limit"] == limits["max_load_g"]
    assert shown.loc["entry peak heat rate", "peak"] == plan.reentry.max_heat_rate_w_m2 / 1e3
    assert frame["within"].all()  # a plan of the pipeline keeps within every limit


# --- a flight of the plan passed in ------------------------------------------------------


@pytest.fixture(scope="module")
def report_inputs(plan_json, plan, scenario) -> dict[str, Any]:
    """What ``ovtraj pipeline`` gave :func:`write_report` for the plan (no plots)."""
    from ovtraj.optimize import Normalisation
    from ovtraj.pipeline.loop import load_pipeline

    result = load_pipeline(plan_json.parent.parent)  # <pipeline>/plans/<plan>.json
    return {
        "scenario_name": scenario.name,
        "normalisation": Normalisation.mission(scenario.mission.optimize),
        "summary": result.summary,
        "verify": scenario.mission.verify,
        "front": result.front,
        "plan": plan,
        "pick_text": "the plan of the last night",
        "surrogates": None,
        "plots": [],
    }


def _flown_section(path: Path) -> str:
    text = path.read_text(encoding="utf-8")
    start = text.index("<h2>Flown</h2>")
    return text[start : text.index("<h2>", start + 1)]


def test_the_report_says_no_flight_is_stored_and_shows_one_passed_in(
    plan, report, report_inputs, tmp_path
):
    """No flight is stored with a new plan: the pipeline's report says so and how to store
    one. A replay passed in as ``ovtraj fly PLAN --json`` prints it is shown beside the
    plan's own figures."""
    from ovtraj.mission.fly import fly_plan
    from ovtraj.pipeline.report import write_report
    from ovtraj.pipeline.report_tables import flight_shown
    from ovtraj.store.records import json_text

    assert "No flight of this plan is stored" in _flown_section(report)
    replay = fly_plan(plan)
    flown = json.loads(json_text(replay.to_dict(), indent=None))  # as the command prints it
    sentence, frame = flight_shown(flown, plan)
    assert "landed within the stated miss" in sentence and "completed" in sentence
    rows = frame.set_index("quantity")
    dv = sum(burn.dv_mps for burn in replay.burns)
    t_total_h = (replay.terminal["t_s"] - plan.launch.drop_t_s) / 3600.0
    assert float(rows.loc["dV_total", "flown (J2 replay)"]) == pytest.approx(dv, rel=1e-5)
    assert float(rows.loc["T_total", "flown (J2 replay)"]) == pytest.approx(t_total_h, rel=1e-5)
    assert float(rows.loc["T_total", "plan"]) == pytest.approx(
        plan.totals.t_total_s / 3600.0, rel=1e-5
    )
    assert float(rows.loc["landing miss", "flown (J2 replay)"]) == pytest.approx(
        replay.miss_distance_m / 1e3, rel=1e-5
    )
    heat = replay.checks["max_heat_rate_w_m2"].value / 1e3
    assert float(rows.loc["entry peak heat rate", "flown (J2 replay)"]) == pytest.approx(
        heat, rel=1e-5
    )
    path = write_report(tmp_path / "flown.html", **report_inputs, flights=[flown])
    section = _flown_section(path)
    assert "replayed open-loop from the drop" in section and "flown (J2 replay)" in section


def test_a_hostile_or_foreign_flight_is_shown_as_text_or_refused(plan, report_inputs, tmp_path):
    """Text is escaped and cut, a figure that is no number is ``-``; the flight of another
    plan, or a mapping of neither kind, is refused and nothing is written."""
    from ovtraj.mission.fly import fly_plan
    from ovtraj.pipeline.report import write_report
    from ovtraj.pipeline.report_tables import FlightResultError
    from ovtraj.store.records import json_text

    flown = json.loads(json_text(fly_plan(plan).to_dict(), indent=None))
    hostile = {
        **flown,
        "reason": "<script>alert(1)</script>" * 100,
        "miss_distance_m": "far",
        "rendezvous_arrival_miss_m": 10**400,  # beyond any float
    }
    path = write_report(tmp_path / "hostile.html", **report_inputs, flights=[hostile])
    section = _flown_section(path)
    assert "<script>" not in section and "&lt;script&gt;" in section
    assert len(section) < len(hostile["reason"])  # the reason cut to a line
    for quantity, unit in (("landing miss", "km"), ("rendezvous arrival miss", "m")):
        row = re.search(f"<tr><td>{quantity}</td>(.*?)</tr>", section)
        assert row, f"no row {quantity!r} in {section}"
        # flown and flown - plan: no figure
        assert row.group(1).endswith(f"<td>-</td><td>-</td><td>{unit}</td>"), row.group(1)
    other = {**flown, "predicted_miss_distance_m": plan.terminal.miss_distance_m + 1.0}
    for flight, words in ((other, "not a flight of this plan"), ({"ok": True}, "neither")):
        target = tmp_path / "refused.html"
        with pytest.raises(FlightResultError, match=words):
            write_report(target, **report_inputs, flights=[flight])
        assert not target.exists()


def test_the_high_fidelity_flight_is_shown_beside_the_plan(plan, scenario):
    """The closed loops of ``ovtraj fly PLAN --fidelity high`` (no dispersion, the J2 and
    the shipped high-fidelity skies), flown here: each manoeuvre's dV and the margins
    beside the plan's."""
    from ovtraj.config.dispersions import default_dispersions
    from ovtraj.mission.high_fidelity import high_fidelity_settings
    from ovtraj.mission.montecarlo_outcome import MANOEUVRES
    from ovtraj.mission.montecarlo_statistics import path_limits
    from ovtraj.mission.sky_flight import fidelity_report, fly_nominal
    from ovtraj.pipeline.report_tables import flight_shown
    from ovtraj.store.records import json_text

    dispersions = default_dispersions()  # the shipped configs/dispersions.yaml
    settings = high_fidelity_settings(plan, "high", None)
    j2 = fly_nominal(plan, dispersions, scenario=scenario)
    high = fly_nominal(plan, dispersions, settings, scenario=scenario)
    found = fidelity_report(plan, j2, high, settings)
    flown = json.loads(json_text(found, indent=None))
    sentence, frame = flight_shown(flown, plan)
    assert "closed-loop without dispersions" in sentence
    rows = frame.set_index("quantity")
    for name in MANOEUVRES:
        value = high.dv_mps.get(name)
        shown = rows.loc[f"{name} dV", "closed loop, high fidelity"]
        assert shown == "-" if value is None else float(shown) == pytest.approx(value, rel=1e-5)
    assert float(rows.loc["dV_total", "plan"]) == pytest.approx(plan.totals.dv_total_mps, 1e-5)
    limit = path_limits(plan)["max_load_g"]
    assert float(rows.loc["entry load-factor margin", "plan"]) == pytest.approx(
        limit - plan.reentry.max_load_g, rel=1e-5
    )
    assert float(rows.loc["entry load-factor margin", "closed loop, J2"]) == pytest.approx(
        limit - j2.maxima["max_load_g"], rel=1e-5
    )
