"""The scenario's space target: hand-typed elements, or a real element set (TLE, OMM, URL).

A target is given by exactly one of

* ``orbit``: classical elements typed by hand (``element_set: osculating | mean``);
* ``tle_file`` / ``tle``: a two- or three-line element set, in a file or inline;
* ``omm_file`` / ``omm``: a CCSDS OMM (XML, KVN, or CelesTrak's JSON / CSV), in a
  file or inline as a mapping of its fields;
* ``url``: an http(s) address serving a TLE or an OMM.

A file or URL is read by the scenario loader (:func:`ovtraj.target_sources.load_scenario`,
never by validation) and replaced by its inline form (``tle:`` lines or ``omm:`` fields),
so the resolved scenario (what a run
stores and what its id hashes) carries the element set itself: a replay needs
neither the file nor the network, and a changed element set is a changed
scenario. Relative files are relative to the scenario file's folder. How SGP4's
ephemeris becomes the project's mean elements is in ``docs/targets.md``.

The fit and fetch settings (``source_settings``) default to the shipped
``configs/target_sources.yaml`` (added by the loader), as the Earth model defaults to
``configs/earth.yaml``; a target with a source always carries them in the resolved
scenario, a hand-typed one does not need them (and dumps as before: ``name`` and
``orbit``).
"""

from __future__ import annotations

import re
from functools import lru_cache
from typing import Any, Literal

from pydantic import Field, field_validator, model_serializer, model_validator

from ovtraj.astro.elements import perigee_radius
from ovtraj.config.base import ConfigError, StrictModel, bounded, load_model
from ovtraj.config.body import TargetBodyConfig
from ovtraj.element_sets.elements import SourceElements
from ovtraj.element_sets.inline import inline_elements
from ovtraj.units import BYTES_PER_MIB, S_PER_HOUR

ElementSet = Literal["osculating", "mean"]

# The keys that name where the target's orbit comes from; exactly one is given.
SOURCE_KEYS = ("orbit", "tle_file", "tle", "omm_file", "omm", "url")
# The ones read at validation and replaced by their inline form.
READ_KEYS = ("tle_file", "omm_file", "url")
# Samples of the SGP4 ephemeris one fit may use: one fit evaluation stays well under
# 0.1 s (a day at one sample per minute is 1441).
_MAX_FIT_SAMPLES = 100_000
# A host name as a redirect's host is compared with it: a DNS name or an IPv4 address
# (letters, digits, dots and hyphens), no scheme, port or path.
_HOST_NAME = re.compile(r"[a-z0-9]([a-z0-9.-]*[a-z0-9])?")


class OrbitElementsConfig(StrictModel):
    """Classical elements at the scenario epoch; ``mean`` means first-order J2 (Brouwer) mean."""

    element_set: ElementSet = "osculating"
    semi_major_axis_km: float = bounded(unit="km", gt=0, le=1.0e6)
    eccentricity: float = bounded(ge=0, lt=1)
    inclination_deg: float = bounded(unit="deg", ge=0, le=180)
    raan_deg: float = bounded(unit="deg", ge=-360, le=360)
    arg_perigee_deg: float = bounded(unit="deg", ge=-360, le=360)
    true_anomaly_deg: float = bounded(unit="deg", ge=-360, le=360)

    def perigee_altitude_km(self, radius_m: float) -> float:
        return perigee_radius(self.semi_major_axis_km, self.eccentricity) - radius_m / 1e3


class TargetSourceSettings(StrictModel):
    """How a TLE / OMM / URL target is read and fitted (``docs/targets.md``)."""

    fit_span_h: float = bounded(
        unit="h", gt=0, le=240, description="SGP4 span the mean elements are fitted over"
    )
    fit_step_s: float = bounded(unit="s", ge=1, le=3600, description="SGP4 sample spacing")
    fit_max_iterations: int = bounded(
        ge=1, le=10000, description="least-squares function evaluations"
    )
    fit_time_limit_s: float = bounded(unit="s", gt=0, le=3600, description="fit wall time")
    fit_warning_km: float = bounded(
        unit="km", gt=0, le=10000, description="a larger max. fit error warns"
    )
    max_age_days: float = bounded(
        unit="day", gt=0, le=3650, description="an element set this far from the epoch warns"
    )
    url_timeout_s: float = bounded(
        unit="s",
        gt=0,
        le=600,
        description="a URL's whole fetch: connection, redirects, headers and body",
    )
    url_cache_max_age_h: float = bounded(
        unit="h", ge=0, le=8760, description="a URL fetched this recently is read from the cache"
    )
    url_max_mib: float = bounded(
        unit="MiB", gt=0, le=1024, description="largest URL download or element-set file"
    )
    url_redirect_hosts: list[str] = Field(
        # Empty when absent: a scenario stored before the setting existed still validates,
        # and refuses every redirect to another host.
        default_factory=list,
        description="hosts a URL may redirect to besides its own (none: no other host)",
    )

    @field_validator("url_redirect_hosts")
    @classmethod
    def _host_names(cls, hosts: list[str]) -> list[str]:
        """Host names as the fetch compares them: lower case, no port, no scheme."""
        from ovtraj.config.io_limits import echoed

        names = [host.strip().lower() for host in hosts]
        for name in names:
            if not _HOST_NAME.fullmatch(name):
                shown = echoed(repr(name))
                raise ValueError(f"{shown} is not a host name (e.g. celestrak.org, no scheme)")
        return names

    @model_serializer(mode="wrap")
    def _no_empty_allow_list(self, handler: Any) -> dict[str, Any]:
        """``url_redirect_hosts`` left out while empty: the resolved scenario of a target
        with a source (and so its run ids) is unchanged from before the setting."""
        dumped = handler(self)
        if not dumped.get("url_redirect_hosts"):
            dumped.pop("url_redirect_hosts", None)
        return dumped

    @property
    def max_bytes(self) -> int:
        """``url_max_mib`` in bytes [B]: the largest download or element-set file."""
        return int(self.url_max_mib * BYTES_PER_MIB)

    @model_validator(mode="after")
    def _samples_in_reach(self) -> TargetSourceSettings:
        span_s = self.fit_span_h * S_PER_HOUR
        if self.fit_step_s > span_s:
            raise ValueError(
                f"fit_step_s = {self.fit_step_s:g} s is longer than fit_span_h = "
                f"{self.fit_span_h:g} h"
            )
        if span_s / self.fit_step_s > _MAX_FIT_SAMPLES:
            raise ValueError(
                f"fit_span_h / fit_step_s gives {span_s / self.fit_step_s:.0f} samples "
                f"(allowed <= {_MAX_FIT_SAMPLES})"
            )
        return self


@lru_cache(maxsize=1)
def default_source_settings() -> TargetSourceSettings:
    """The shipped ``configs/target_sources.yaml``."""
    from ovtraj.paths import config_path

    return load_model(TargetSourceSettings, config_path("target_sources.yaml"))


class TargetConfig(StrictModel):
    """The space target: exactly one of ``orbit``, ``tle_file``, ``tle``, ``omm_file``,
    ``omm``, ``url`` (the module notes), plus the settings a real source needs."""

    name: str
    orbit: OrbitElementsConfig | None = None
    tle: list[str] | None = Field(
        default=None, min_length=2, max_length=3, description="TLE lines (name line optional)"
    )
    omm: dict[str, str | int | float] | None = Field(
        default=None, description="the fields of one OMM element set"
    )
    tle_file: str | None = Field(default=None, description="read and replaced by tle")
    omm_file: str | None = Field(default=None, description="read and replaced by omm")
    url: str | None = Field(default=None, description="fetched and replaced by tle or omm")
    catalog_number: int | None = bounded(
        ge=0, le=999_999_999, default=None, description="picks one element set of several"
    )
    source_settings: TargetSourceSettings | None = None
    body: TargetBodyConfig | None = Field(
        default=None, description="drag and radiation pressure figures (the high-fidelity flight)"
    )

    @model_validator(mode="before")
    @classmethod
    def _one_inline_source(cls, data: Any) -> Any:
        """Exactly one source, given inline: a file or URL is read by the scenario loader
        (:func:`ovtraj.target_sources.load_scenario`), never by validation (checking a model
        reads no file and no network)."""
        if not isinstance(data, dict):
            return data
        given = [key for key in SOURCE_KEYS if data.get(key) is not None]
        if len(given) != 1:
            found = ", ".join(given) if given else "none"
            raise ValueError(f"needs exactly one of {', '.join(SOURCE_KEYS)} (found: {found})")
        if given[0] in READ_KEYS:
            raise ValueError(
                f"{given[0]}: a file or URL is read by the scenario loader "
                "(ovtraj.target_sources.load_scenario), not by validation"
            )
        if given[0] != "orbit" and data.get("source_settings") is None:
            raise ValueError(
                "source_settings: needed with a tle or omm element set (the scenario loader "
                "adds the shipped configs/target_sources.yaml)"
            )
        return data

    @model_validator(mode="after")
    def _source_is_readable(self) -> TargetConfig:
        if self.orbit is not None:
            return self
        try:
            self.elements()  # the inline element set parses (checksums, fields)
        except ConfigError as err:
            raise ValueError("; ".join(err.problems)) from None
        return self

    @model_serializer(mode="wrap")
    def _only_what_is_given(self, handler: Any) -> dict[str, Any]:
        """Keys left empty are left out: a hand-typed target dumps as ``name`` and ``orbit``
        alone, as before sources existed, so its run ids and launch-fit keys are unchanged."""
        return {k: v for k, v in handler(self).items() if v is not None}

    @property
    def has_source(self) -> bool:
        """Whether the orbit comes from a TLE or OMM (fitted), not from typed elements."""
        return self.orbit is None

    def perigee_altitude_km(self, radius_m: float) -> float:
        """Perigee altitude [km] above a sphere of ``radius_m``: of the typed elements, or
        of the element set's SGP4 mean elements (a plausibility check, no fit)."""
        if self.orbit is not None:
            return self.orbit.perigee_altitude_km(radius_m)
        return self.elements().perigee_radius_km() - radius_m / 1e3

    def elements(self) -> SourceElements:
        """The inline element set (``tle`` or ``omm``), parsed and checked against
        ``catalog_number``; :class:`ConfigError` for a hand-typed orbit."""
        return inline_elements(self.tle, self.omm, self.catalog_number)

    @property
    def source_key(self) -> str:
        """The key the orbit was given by after resolution: ``orbit``, ``tle`` or ``omm``."""
        return "orbit" if self.orbit is not None else ("tle" if self.tle is not None else "omm")
