"""Epochs, Julian dates and GMST against published values."""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta, timezone

import numpy as np
import pytest

from ovtraj.astro.epoch import (
    Epoch,
    earth_rotation_angle,
    gmst_rad,
    julian_date,
)
from ovtraj.config.physical import default_earth
from ovtraj.units import J2000_JD

# ---------------------------------------------------------------- Julian date


def test_julian_date_vallado_example_3_4() -> None:
    # Vallado 4th ed. Example 3-4: 1996 October 26, 14:20 UT -> JD 2,450,383.097 222 22.
    jd_day, fraction = julian_date(1996, 10, 26, 14, 20, 0.0)
    assert jd_day == 2450382.5  # 0 h of the day
    assert jd_day + fraction == pytest.approx(2450383.09722222, abs=1e-8)


def test_julian_date_of_j2000() -> None:
    # J2000.0 = 2000 January 1, 12:00 = JD 2,451,545.0 (Vallado eq. 3-42).
    assert sum(julian_date(2000, 1, 1, 12)) == J2000_JD


def test_julian_date_is_vectorised() -> None:
    jd_day, fraction = julian_date(np.array([1996, 2000]), np.array([10, 1]), np.array([26, 1]))
    np.testing.assert_array_equal(jd_day, [2450382.5, 2451544.5])
    np.testing.assert_array_equal(fraction, [0.0, 0.0])


@pytest.mark.parametrize("date", [(1899, 12, 31), (2100, 3, 1), (2026, 13, 1), (2026, 1, 0)])
def test_julian_date_rejects_dates_outside_algorithm_14(date: tuple[int, int, int]) -> None:
    with pytest.raises(ValueError):
        julian_date(*date)


# ----------------------------------------------------------------------- GMST


def test_gmst_vallado_example_3_5() -> None:
    # Vallado 4th ed. Example 3-5: 1992 August 20, 12:14 UT1 -> GMST = 152.578 787 810 deg.
    gmst = gmst_rad(*julian_date(1992, 8, 20, 12, 14))
    assert math.degrees(gmst) == pytest.approx(152.578787810, abs=1e-6)


def test_gmst_at_j2000() -> None:
    # T_UT1 = 0: GMST = 67310.54841 s = 280.460 618 37 deg (IAU-82; Meeus eq. 12.4).
    assert math.degrees(gmst_rad(J2000_JD)) == pytest.approx(280.46061837, abs=1e-8)


def test_gmst_meeus_examples_12a_12b() -> None:
    # Meeus, Astronomical Algorithms 2nd ed., Example 12.a: 1987 April 10, 0 h UT
    # -> 13h10m46.3668s; Example 12.b: same day 19:21 UT -> 128.737 8734 deg.
    gmst_0h = math.degrees(gmst_rad(*julian_date(1987, 4, 10)))
    assert gmst_0h == pytest.approx(15.0 * (13 + 10 / 60 + 46.3668 / 3600), abs=1e-6)
    gmst_1921 = math.degrees(gmst_rad(*julian_date(1987, 4, 10, 19, 21)))
    assert gmst_1921 == pytest.approx(128.7378734, abs=1e-6)


def test_gmst_two_part_split_does_not_matter() -> None:
    whole = gmst_rad(2460000.5, 0.123456789)
    assert gmst_rad(2457000.5, 3000.123456789) == pytest.approx(whole, abs=1e-10)
    # A single float Julian date resolves ~4e-5 s, i.e. ~3e-9 rad of Earth rotation.
    assert gmst_rad(2460000.5 + 0.123456789) == pytest.approx(whole, abs=1e-8)


def test_gmst_vectorised_and_in_range() -> None:
    jd2 = np.linspace(0.0, 3.0, 1001)
    gmst = gmst_rad(2461100.5, jd2)
    assert gmst.shape == jd2.shape
    assert np.all((gmst >= 0.0) & (gmst < 2.0 * np.pi))
    expected = [gmst_rad(2461100.5, f) for f in jd2[::100]]
    np.testing.assert_allclose(gmst[::100], expected, rtol=0, atol=1e-12)


def test_gmst_advances_one_sidereal_turn_per_sidereal_day() -> None:
    # The mean sidereal day is 86164.0905 s (IAU-82 rate 1.002737909 turns per solar day).
    epoch = Epoch.from_iso("2026-03-01T00:00:00Z")
    later = epoch.plus_seconds(86164.0905)
    assert later.gmst_rad() == pytest.approx(epoch.gmst_rad(), abs=1e-7)


# ---------------------------------------------------------------------- Epoch


def test_from_iso_offsets_are_converted_to_utc() -> None:
    zulu = Epoch.from_iso("2026-03-01T12:00:00Z")
    assert Epoch.from_iso("2026-03-01T14:00:00+02:00") == zulu
    assert Epoch.from_iso("2026-03-01T07:30:00-04:30") == zulu
    assert Epoch.from_iso("2026-03-01T12:00:00") == zulu  # naive = UTC
    assert zulu.jd == pytest.approx(2461101.0, abs=1e-9)


@pytest.mark.parametrize("text", ["2026-13-01", "tomorrow", "", "2026-03-01T25:00:00Z"])
def test_from_iso_rejects_bad_text_naming_it(text: str) -> None:
    with pytest.raises(ValueError, match="ISO 8601") as info:
        Epoch.from_iso(text)
    assert repr(text) in str(info.value)


def test_from_iso_rejects_dates_outside_the_julian_date_algorithm() -> None:
    with pytest.raises(ValueError, match="'1850-01-01'"):
        Epoch.from_iso("1850-01-01")


def test_iso_format_and_round_trip() -> None:
    text = "2026-03-01T12:00:00.000000Z"
    assert Epoch.from_iso(text).iso() == text
    odd = Epoch.from_iso("2031-07-15T23:59:59.999999+05:30")
    assert odd.iso() == "2031-07-15T18:29:59.999999Z"
    assert Epoch.from_iso(odd.iso()) == odd


def test_iso_with_nanoseconds_rounds_at_its_own_digit() -> None:
    """The CCSDS export's epochs (9 digits): the same instant as the microsecond text,
    rounded at the ninth digit, carrying into the next second and day."""
    day = Epoch.from_iso("2026-12-01T00:00:00Z")
    assert day.plus_seconds(298949.45367543).iso(digits=9) == "2026-12-04T11:02:29.453675430Z"
    assert day.plus_seconds(298949.45367543).iso() == "2026-12-04T11:02:29.453675Z"
    assert day.plus_seconds(86399.9999999996).iso(digits=9) == "2026-12-02T00:00:00.000000000Z"
    assert day.plus_seconds(59.4).iso(digits=0) == "2026-12-01T00:00:59Z"
    rng = np.random.default_rng(3)
    for seconds in rng.uniform(-1e7, 1e7, 2000):
        epoch = day.plus_seconds(float(seconds))
        assert epoch.iso() == epoch.to_datetime().strftime("%Y-%m-%dT%H:%M:%S.%fZ")
        nano = epoch.iso(digits=9)
        assert abs(Epoch.from_iso(nano).seconds_since(epoch)) <= 1e-6  # from_iso: microseconds


def test_datetime_round_trip_is_aware_utc() -> None:
    dt = datetime(2024, 2, 29, 6, 7, 8, 123456, tzinfo=timezone(timedelta(hours=-3)))
    back = Epoch.from_datetime(dt).to_datetime()
    assert back.tzinfo is not None and back.utcoffset() == timedelta(0)
    assert back == dt


def test_constructor_normalises_the_two_parts() -> None:
    epoch = Epoch(J2000_JD, 0.0)
    assert (epoch.jd1, epoch.jd2) == (J2000_JD - 0.5, 0.5)
    assert Epoch(J2000_JD - 10.0, 10.0) == epoch
    assert Epoch(J2000_JD, -0.75).iso() == "1999-12-31T18:00:00.000000Z"
    with pytest.raises(ValueError):
        Epoch(math.nan, 0.0)


def test_plus_seconds_and_seconds_since_over_long_spans() -> None:
    start = Epoch.from_iso("2001-05-17T03:04:05.678901Z")
    for span_s in (1e-6, 0.3, 86399.999999, 1.0e6 + 0.123456, -7.3e8 - 0.5, 2.9e9 + 0.654321):
        later = start.plus_seconds(span_s)
        assert later.seconds_since(start) == pytest.approx(span_s, abs=1e-6)
        assert start.seconds_since(later) == pytest.approx(-span_s, abs=1e-6)
        # Independent reference: datetime arithmetic (leap seconds ignored as well).
        assert later.to_datetime() == start.to_datetime() + timedelta(seconds=span_s)


def test_many_small_steps_match_one_large_step() -> None:
    start = Epoch.from_iso("2026-03-01T00:00:00Z")
    stepped = start
    for _ in range(10_000):
        stepped = stepped.plus_seconds(8.64)
    assert stepped.seconds_since(start.plus_seconds(86400.0)) == pytest.approx(0.0, abs=1e-6)
    assert stepped.iso() == "2026-03-02T00:00:00.000000Z"


def test_epochs_order_chronologically() -> None:
    early = Epoch.from_iso("2026-03-01T23:59:59Z")
    late = Epoch.from_iso("2026-03-02T00:00:00Z")
    assert early < late and sorted([late, early]) == [early, late]


def test_epoch_gmst_matches_function() -> None:
    epoch = Epoch.from_datetime(datetime(1992, 8, 20, 12, 14, tzinfo=UTC))
    assert math.degrees(epoch.gmst_rad()) == pytest.approx(152.578787810, abs=1e-6)


# ------------------------------------------------------- Earth rotation angle


def test_earth_rotation_angle_is_linear_from_gmst() -> None:
    omega = default_earth().omega
    epoch = Epoch.from_iso("2026-03-01T12:00:00Z")
    t = np.array([0.0, 60.0, 86400.0 * 3])
    theta = earth_rotation_angle(epoch, t, omega=omega)
    assert theta.shape == t.shape
    assert theta[0] == epoch.gmst_rad()
    np.testing.assert_allclose(np.diff(theta), omega * np.diff(t), rtol=1e-12, atol=1e-14)
    # Over a day the linear model and IAU-82 GMST agree to the rate difference
    # (omega_E = 7.2921159e-5 vs 7.2921158553e-5 rad/s): ~4e-8 rad.
    day_later = epoch.plus_seconds(86400.0).gmst_rad()
    one_day = earth_rotation_angle(epoch, 86400.0, omega=omega)
    assert np.mod(one_day - day_later + np.pi, 2 * np.pi) - np.pi == pytest.approx(0.0, abs=1e-7)
