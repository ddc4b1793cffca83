"""The plots: coastlines, ground track, corridor limits, fronts, hours."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import MissionContext, MissionDesign, evaluate
from ovtraj.optimize.objectives import Normalisation
from ovtraj.paths import reference_dir
from ovtraj.plots.coastlines import (
    COASTLINE_FILE,
    load_coastlines,
    split_at_wrap,
    with_breaks,
)
from ovtraj.plots.front import front_figure, front_plot
from ovtraj.plots.mission import mission_figures, mission_plots
from ovtraj.plots.render import png_bytes
from ovtraj.plots.surrogate import display_unit, parity_figure
from tests.conftest import build_scenario

PNG = b"\x89PNG\r\n\x1a\n"


def _densified(lon: np.ndarray, lat: np.ndarray, step: float = 0.25) -> np.ndarray:
    """A polyline's points every <= ``step`` deg (linear in lon/lat), as (n, 2)."""
    parts = []
    for k in range(len(lon) - 1):
        n = max(1, math.ceil(max(abs(lon[k + 1] - lon[k]), abs(lat[k + 1] - lat[k])) / step))
        f = np.arange(n) / n
        parts.append(np.c_[lon[k] + f * (lon[k + 1] - lon[k]), lat[k] + f * (lat[k + 1] - lat[k])])
    parts.append(np.c_[lon[-1:], lat[-1:]])
    return np.vstack(parts)


@pytest.fixture(scope="module")
def coast_points() -> np.ndarray:
    return np.vstack([_densified(lon, lat) for lon, lat in load_coastlines().polylines])


def _nearest_deg(points: np.ndarray, lat: float, lon: float) -> float:
    """Great-circle distance [deg] from (lat, lon) to the nearest of ``points`` (lon, lat)."""
    p1, p2 = math.radians(lat), np.radians(points[:, 1])
    dl = np.radians(points[:, 0] - lon)
    h = np.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * np.cos(p2) * np.sin(dl / 2) ** 2
    return float(np.degrees(2 * np.arcsin(np.sqrt(np.minimum(h, 1.0)))).min())


# -- coastlines -----------------------------------------------------------------------------


def test_coastline_file_is_shipped_reference_data_with_its_source():
    path = reference_dir() / COASTLINE_FILE
    header = json.loads(path.read_text(encoding="utf-8"))
    assert "Natural Earth" in header["source"] and "land-110m.json" in header["source"]
    assert "public domain" in header["licence"]
    assert "4.1.0" in header["version"] and header["made_by"] == "tools/make_coastlines.py"
    assert load_coastlines().header["source"] == header["source"]


def test_coastlines_are_plausible_110m_land_polylines():
    coast = load_coastlines()
    assert 100 <= len(coast.polylines) <= 300
    assert 4000 <= coast.points <= 8000  # Natural Earth 1:110m land: ~5100 vertices
    for lon, lat in coast.polylines:
        assert len(lon) == len(lat) >= 2
        assert np.all((lon >= -180.0) & (lon <= 180.0))
        assert np.all((lat >= -90.0) & (lat <= 90.0))
        assert np.all(np.abs(np.diff(lon)) < 180.0)  # no line across the map
        on_edge = np.abs(lon) >= 180.0
        assert not np.any(on_edge[1:] & on_edge[:-1])  # no antimeridian cut edge
    assert min(lat.min() for _, lat in coast.polylines) < -70.0  # Antarctica


@pytest.mark.parametrize(
    ("place", "lat", "lon", "low", "high"),
    [
        ("Cape Canaveral", 28.5, -80.6, 0.0, 2.0),
        ("Strait of Gibraltar", 36.0, -5.6, 0.0, 1.0),
        ("Cape Horn", -55.98, -67.27, 0.0, 1.5),
        ("Hawaii (Big Island)", 19.6, -155.5, 0.0, 1.5),
        ("mid-Pacific", 0.0, -160.0, 5.0, 180.0),
        ("South Pacific", -40.0, -120.0, 20.0, 180.0),
        ("North Pole (Arctic Ocean)", 90.0, 0.0, 5.0, 180.0),
    ],
)
def test_coastlines_where_they_are_known_to_be(coast_points, place, lat, lon, low, high):
    distance = _nearest_deg(coast_points, lat, lon)
    assert low <= distance <= high, f"{place}: nearest coast {distance:.2f} deg"


# -- the +-180 deg wrap ---------------------------------------------------------------------


def test_a_track_crossing_180_east_is_split_into_two_segments():
    lon = np.array([160.0, 170.0, -170.0, -160.0])
    lat = np.array([0.0, 10.0, 30.0, 40.0])
    pieces = split_at_wrap(lon, lat)
    assert len(pieces) == 2
    (x1, y1), (x2, y2) = pieces
    np.testing.assert_allclose(x1, [160.0, 170.0, 180.0])
    np.testing.assert_allclose(y1, [0.0, 10.0, 20.0])  # halfway from 170 to -170 (=190)
    np.testing.assert_allclose(x2, [-180.0, -170.0, -160.0])
    np.testing.assert_allclose(y2, [20.0, 30.0, 40.0])


def test_a_track_crossing_minus_180_west_and_twice_is_split_at_each_crossing():
    pieces = split_at_wrap(np.array([-175.0, 175.0]), np.array([0.0, 10.0]))
    assert [p[0].tolist() for p in pieces] == [[-175.0, -180.0], [180.0, 175.0]]
    np.testing.assert_allclose([p[1][-1] for p in pieces], [5.0, 10.0])
    # three orbits' worth of longitude: two crossings, three pieces, none across the map
    t = np.linspace(0.0, 720.0, 241)
    lon = (t + 180.0) % 360.0 - 180.0
    pieces = split_at_wrap(lon, np.sin(np.radians(t)) * 50.0)
    assert len(pieces) == 3
    assert all(np.all(np.abs(np.diff(x)) < 180.0) for x, _ in pieces)


def test_split_keeps_a_line_without_crossing_and_cuts_at_nan():
    lon, lat = np.array([-10.0, 0.0, 10.0]), np.array([1.0, 2.0, 3.0])
    ((x, y),) = split_at_wrap(lon, lat)
    np.testing.assert_array_equal(x, lon)
    np.testing.assert_array_equal(y, lat)
    pieces = split_at_wrap(np.array([0.0, 1.0, np.nan, 2.0, 3.0]), np.zeros(5))
    assert [p[0].tolist() for p in pieces] == [[0.0, 1.0], [2.0, 3.0]]
    x, _ = with_breaks(pieces)
    assert np.isnan(x[2]) and len(x) == 5
    with pytest.raises(ValueError, match="1-D of one length"):
        split_at_wrap(np.zeros(3), np.zeros(2))


# -- mission plots --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def record(scenario):
    fit = find_launch_fit(scenario)
    assert fit is not None, "the reference launch fit must match the default scenario"
    record = evaluate(MissionContext(scenario, fit), MissionDesign(262.9, 345.8, 15.2))
    assert record.feasible, record.reason
    return record


@pytest.fixture(scope="module")
def figures(record, scenario):
    return mission_figures(record.trajectories, scenario)


def _legend_texts(fig) -> list[str]:
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    return [text.get_text() for legend in legends for text in legend.get_texts()]


def test_ground_track_has_coastlines_and_no_line_across_the_map(figures, scenario):
    fig = figures["ground_track"]
    world, near = fig.axes
    coast = [line for line in world.get_lines() if line.get_color() == "0.55"]
    assert coast and np.isfinite(coast[0].get_xdata()).sum() >= load_coastlines().points
    for ax in (world, near):
        for line in ax.get_lines():
            x = np.asarray(line.get_xdata(), dtype=float)
            steps = np.abs(np.diff(x))
            assert np.all(steps[np.isfinite(steps)] < 180.0), line.get_label()
    for ax in (world, near):
        assert "longitude [deg" in ax.get_xlabel() and "latitude [deg]" in ax.get_ylabel()
    texts = " | ".join(_legend_texts(fig))
    site = scenario.reentry.landing_site
    entry = scenario.deorbit.entry
    for needed in (
        "entry region",
        f"{entry.latitude_deg:g} ± {entry.latitude_tolerance_deg:g}° lat",
        "entry point",
        "terminal point",
        f"landing site: {site.name}",
        "coastlines (Natural Earth 1:110m)",
        "rendezvous: phasing in the parking orbit",
        "deorbit: descent to the entry interface",
        "reentry",
    ):
        assert needed in texts, needed
    assert scenario.name in fig.get_suptitle()


def test_terminal_point_is_drawn_above_and_smaller_than_the_landing_site(figures):
    near = figures["ground_track"].axes[1]
    lines = {line.get_label().split(" (")[0]: line for line in near.get_lines()}
    terminal = lines["terminal point"]
    site = next(v for k, v in lines.items() if k.startswith("landing site"))
    assert terminal.get_zorder() > site.get_zorder()
    assert terminal.get_markersize() < site.get_markersize()
    assert site.get_markerfacecolor() == "none"  # a ring: what is under it stays visible
    region = [p for p in near.patches if "entry region" in p.get_label()]
    assert region and region[0].get_edgecolor()[3] > 0 and region[0].get_facecolor()[3] > 0.5


def test_corridor_legend_names_each_limit_with_its_value_from_the_scenario(record, scenario_data):
    limits = scenario_data["reentry"]["limits"]
    limits.update(max_dynamic_pressure_kpa=15.0, max_load_g=2.75, max_heat_rate_kw_m2=1234.0)
    changed = build_scenario(scenario_data)
    fig = mission_figures(record.trajectories, changed)["reentry_corridor"]
    texts = _legend_texts(fig)
    assert any("dynamic pressure" in t and "15 kPa" in t for t in texts), texts
    assert any("load factor" in t and "2.75 g" in t for t in texts), texts
    assert any("heat-rate" in t and "1234 kW/m²" in t for t in texts), texts
    terminal = changed.reentry.terminal
    assert f"terminal speed {terminal.speed_mps:g} m/s" in texts
    # the q contour is drawn at the configured level (Pa)
    levels = [float(c.levels[0]) for c in fig.axes[0].collections if hasattr(c, "levels")]
    assert 15.0e3 in levels


def test_profile_is_in_hours(figures, record):
    left = figures["profile"].axes[0]
    assert "[h]" in left.get_xlabel()
    t_end = max(float(np.nanmax(line.get_xdata())) for line in left.get_lines())
    assert 0.0 < t_end < 24.0 * 10  # hours from the launch day, not 10^5 seconds
    assert t_end == pytest.approx(record.t_total_s / 3600.0, rel=0.5)


def test_mission_plots_write_deterministic_pngs_without_version(record, scenario, tmp_path):
    paths = mission_plots(record.trajectories, scenario, tmp_path / "a", prefix="m")
    again = mission_plots(record.trajectories, scenario, tmp_path / "b", prefix="m")
    assert [p.name for p in paths] == [
        "m_profile.png",
        "m_ground_track.png",
        "m_reentry_corridor.png",
    ]
    for first, second in zip(paths, again, strict=True):
        data = first.read_bytes()
        assert data[:8] == PNG and len(data) > 20_000
        assert b"Software" not in data and b"Matplotlib" not in data
        assert data == second.read_bytes()


# -- fronts ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def normalisation(scenario):
    return Normalisation.mission(scenario.mission.optimize)


def _table(n: int, seed: int) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    return pd.DataFrame(
        {
            "t_total_s": rng.uniform(50.0, 200.0, n) * 3600.0,
            "dv_total_mps": rng.uniform(150.0, 400.0, n),
            "m_load_kg": rng.uniform(100.0, 300.0, n),
        }
    )


def test_front_axes_say_which_way_is_better_and_title_names_scenario_and_date(
    normalisation, scenario
):
    samples = _table(30, 1)
    fig = front_figure(
        normalisation,
        samples=samples,
        verified=samples.iloc[:5],
        title="verified front",
        scenario=scenario.name,
        date=f"epoch {scenario.epoch_utc}",
    )
    labels = [ax.get_xlabel() for ax in fig.axes] + [ax.get_ylabel() for ax in fig.axes]
    assert all("is better" in label for label in labels)
    assert sum("T_total [h] (lower is better" in label for label in labels) == 2
    assert sum("dV_total [m/s] (lower is better" in label for label in labels) == 2
    assert sum("M_load [kg] (higher is better" in label for label in labels) == 2
    title = fig.get_suptitle()
    assert "verified front" in title and scenario.name in title and scenario.epoch_utc in title
    x = fig.axes[0].collections[0].get_offsets()[:, 0]
    np.testing.assert_allclose(x, samples["t_total_s"] / 3600.0)  # hours


def test_front_png_is_byte_identical_for_the_same_data(normalisation, tmp_path):
    table = _table(20, 2)
    kwargs = {"samples": table, "chosen": table.iloc[:1], "scenario": "s", "date": "epoch d"}
    a = front_plot(tmp_path / "a.png", normalisation, **kwargs).read_bytes()
    b = front_plot(tmp_path / "b.png", normalisation, **kwargs).read_bytes()
    assert a[:8] == PNG and a == b and b"Software" not in a


# -- parity plots ---------------------------------------------------------------------------


class _Fitted:
    """The parts of a SurrogateSet a parity plot reads (one output, 30 points)."""

    def __init__(self, output: str, y: np.ndarray) -> None:
        self.output_names = (output,)
        self.selected = {output: "KRG"}
        self.predictions = pd.DataFrame(
            {
                "model": output,
                "split": ["cv"] * (len(y) - 5) + ["heldout"] * 5,
                "y_true": y,
                "y_pred": y * 1.01,
            }
        )
        self.validation = pd.DataFrame(
            {"model": [output], "selected": [True], "cv_q2": [0.99], "heldout_r2": [pd.NA]}
        )


def test_display_units_put_times_in_hours():
    assert display_unit("rendezvous_wait_s") == ("rendezvous_wait", "h", 1.0 / 3600.0)
    assert display_unit("t_total_s") == ("t_total", "h", 1.0 / 3600.0)
    assert display_unit("dv_total_mps") == ("dv_total", "m/s", 1.0)
    assert display_unit("m_load_kg") == ("m_load", "kg", 1.0)
    assert display_unit("feasible") == ("feasible", "", 1.0)


def test_parity_plot_of_a_wait_in_seconds_is_drawn_in_hours():
    y = np.linspace(3600.0, 259_200.0, 30)  # 1 h to the 3-day wait limit
    fig = parity_figure(_Fitted("rendezvous_wait_s", y), "rendezvous_wait_s")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "rendezvous_wait [h] (true)"
    points = np.vstack([c.get_offsets() for c in ax.collections])
    assert points[:, 0].max() == pytest.approx(72.0) and ax.get_xlim()[1] < 100.0
    assert "held-out R² = n/a" in ax.get_title()
    assert png_bytes(fig)[:8] == PNG


def test_views_drawn_on_spawned_processes_are_the_files_drawn_here(normalisation, tmp_path):
    """The pipeline's plots drawn side by side on its pool (``draw_views`` with an
    executor) are the same bytes, written by this process under the views' names."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from ovtraj.pipeline import View, draw_views

    table = _table(20, 3)
    views = [
        View("front.png", front_figure, (normalisation,), {"samples": table, "title": "a"}),
        View("parity-wait.png", parity_figure, (_Fitted("wait_s", table["t_total_s"]), "wait_s")),
        View("other.png", front_figure, (normalisation,), {"verified": table, "title": "b"}),
    ]
    here = draw_views(views, tmp_path / "here")
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        there = draw_views(views, tmp_path / "pool", executor=pool)
    assert [p.name for p in there] == ["front.png", "parity-wait.png", "other.png"]
    assert all(p.parent == tmp_path / "pool" for p in there)
    for a, b in zip(here, there, strict=True):
        assert a.read_bytes()[:8] == PNG and a.read_bytes() == b.read_bytes(), a.name
    assert here[0].read_bytes() != here[2].read_bytes()


def _die() -> None:
    import os

    os._exit(1)  # a worker killed mid-task (out of memory, a signal)


def test_views_are_drawn_here_when_the_pool_broke(normalisation, tmp_path, caplog):
    """A pool whose worker died (``BrokenProcessPool``) draws nothing; this process draws
    the views instead, the same bytes, and says so in the log."""
    import logging
    import multiprocessing
    from concurrent.futures import BrokenExecutor, ProcessPoolExecutor

    from ovtraj.pipeline import View, draw_views

    table = _table(12, 4)
    views = [
        View("front.png", front_figure, (normalisation,), {"samples": table}),
        View("other.png", front_figure, (normalisation,), {"verified": table}),
    ]
    here = draw_views(views, tmp_path / "here")
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        with pytest.raises(BrokenExecutor):
            pool.submit(_die).result()
        with caplog.at_level(logging.WARNING, logger="ovtraj.parallel"):
            drawn = draw_views(views, tmp_path / "broken", executor=pool)
    assert [a.read_bytes() for a in here] == [b.read_bytes() for b in drawn]
    assert "the pool failed (BrokenProcessPool" in caplog.text
    assert "view_png runs in this process" in caplog.text
