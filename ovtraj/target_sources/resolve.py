"""From a scenario's target (or a file, URL or scenario on the command line) to its orbit.

* :func:`inline_target` reads a ``tle_file`` / ``omm_file`` / ``url`` target when the
  scenario is validated and puts the element set inline (``tle:`` / ``omm:``);
* :func:`scenario_with_target_source` is the same for a flow: a scenario (or its
  dict) with its target replaced by a TLE / OMM file, a URL or an inline record;
* :func:`fitted_target` fits a scenario's element set once per process (cached) and
  :func:`fit_source` does it for ``ovtraj target``.

Relative files are relative to ``base_dir`` (the scenario file's folder) when it
is known, else to the current directory.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Mapping
from datetime import UTC, datetime
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.epoch import Epoch
from ovtraj.config.base import ConfigError, model_from_dict
from ovtraj.config.io_limits import echoed
from ovtraj.config.target import (
    READ_KEYS,
    SOURCE_KEYS,
    TargetConfig,
    TargetSourceSettings,
    default_source_settings,
)
from ovtraj.paths import read_text_file
from ovtraj.target_sources.elements import SourceElements, select_element_set
from ovtraj.target_sources.fetch import fetch_text, is_url
from ovtraj.target_sources.fit import TargetFit, fit_target
from ovtraj.target_sources.omm import looks_like_omm, omm_element_sets, omm_elements
from ovtraj.target_sources.tle import tle_element_sets, tle_elements

if TYPE_CHECKING:
    from ovtraj.config.scenario import Scenario

__all__ = [
    "element_sets_from_text",
    "fit_source",
    "fitted_target",
    "inline_target",
    "load_scenario_with_target",
    "read_source",
    "scenario_with_target_source",
    "target_elements",
]

_SCENARIO_SUFFIXES = (".yaml", ".yml")
_SETTINGS_KEY = "target.source_settings"


def element_sets_from_text(text: str, where: str) -> list[SourceElements]:
    """Every element set of a TLE or OMM text (the encoding is recognised from the text)."""
    if looks_like_omm(text):
        return omm_element_sets(text, where)
    return tle_element_sets(text, where)


def _file_text(
    source: str | Path, base_dir: Path | None, settings: TargetSourceSettings
) -> tuple[str, str]:
    """The text of an element-set file and its path: a regular UTF-8 file within
    ``url_max_mib`` (a file may be as large as a download: a whole catalogue)."""
    path = Path(source).expanduser()
    if not path.is_absolute():
        path = (Path(base_dir) if base_dir is not None else Path.cwd()) / path
    limit = f"url_max_mib = {settings.url_max_mib:g} MiB"
    return read_text_file(path, max_bytes=settings.max_bytes, limit=limit), str(path)


def read_source(
    source: str | Path,
    *,
    settings: TargetSourceSettings,
    base_dir: Path | None = None,
    catalog_number: int | None = None,
    cache_dir: Path | None = None,
) -> SourceElements:
    """The element set of a TLE / OMM file or an http(s) URL (fetched through the cache)."""
    if is_url(str(source)):
        where = str(source).strip()
        text = fetch_text(where, settings=settings, cache_dir=cache_dir)
    else:
        text, where = _file_text(source, base_dir, settings)
    return select_element_set(element_sets_from_text(text, where), catalog_number, where)


def _settings(data: Mapping[str, Any]) -> TargetSourceSettings:
    """A target mapping's ``source_settings``, else the shipped default."""
    raw = data.get("source_settings")
    if raw is None:
        return default_source_settings()
    if isinstance(raw, TargetSourceSettings):
        return raw
    return model_from_dict(TargetSourceSettings, raw, _SETTINGS_KEY)


def _catalog_number(data: Mapping[str, Any]) -> int | None:
    value = data.get("catalog_number")
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError([f"catalog_number = {value!r}: expected an integer"])
    return value


def inline_target(
    data: Mapping[str, Any], source_dir: Path | None, cache_dir: Path | None = None
) -> dict[str, Any]:
    """The target mapping with its ``tle_file`` / ``omm_file`` / ``url`` read and replaced
    by the element set's inline form (``tle`` / ``omm``); other keys kept.

    Raises :class:`ConfigError` whose lines start with the key and value
    (``tle_file = 'iss.tle': TLE line 2: checksum ...``).
    """
    key = next(k for k in READ_KEYS if data.get(k) is not None)
    value = data[key]
    try:
        if not isinstance(value, str):
            raise ConfigError(["expected a file name or an http(s) URL as text"])
        if key == "url" and not is_url(value):
            raise ConfigError(["not an http:// or https:// address"])
        settings = _settings(data)
        catalog_number = _catalog_number(data)
        if key == "url":
            elements = read_source(
                value,
                settings=settings,
                catalog_number=catalog_number,
                cache_dir=cache_dir,
            )
        else:
            text, where = _file_text(value, source_dir, settings)
            elements = select_element_set(
                element_sets_from_text(text, where), catalog_number, where
            )
    except ConfigError as err:
        shown = echoed(repr(value))
        raise ConfigError([f"{key} = {shown}: {p}" for p in err.problems]) from None
    resolved = {k: v for k, v in data.items() if k not in READ_KEYS}
    resolved.update(elements.config())
    return resolved


def target_elements(target: TargetConfig) -> SourceElements:
    """The element set of a scenario target given by ``tle`` or ``omm`` (parsed, checked)."""
    if target.tle is not None:
        elements = _tle_cached(tuple(target.tle))
    elif target.omm is not None:
        elements = _omm_cached(json.dumps(target.omm, sort_keys=True))
    else:
        raise ConfigError(["target: hand-typed orbit, no TLE / OMM element set"])
    wanted = target.catalog_number
    if wanted is not None and wanted != elements.catalog_number:
        raise ConfigError(
            [f"catalog_number = {wanted} but the element set is of {elements.catalog_number}"]
        )
    return elements


@lru_cache(maxsize=64)
def _tle_cached(lines: tuple[str, ...]) -> SourceElements:
    return tle_elements(lines, "target.tle")


@lru_cache(maxsize=64)
def _omm_cached(fields_json: str) -> SourceElements:
    return omm_elements(json.loads(fields_json), "target.omm")


def scenario_with_target_source(
    scenario: Scenario | Mapping[str, Any],
    source: str | Path | Mapping[str, Any],
    *,
    base_dir: Path | None = None,
    catalog_number: int | None = None,
    cache_dir: Path | None = None,
) -> dict[str, Any]:
    """A scenario's data with its target's orbit taken from ``source``, ready for
    :func:`ovtraj.config.scenario_from_dict` (no file or network access left in it).

    ``scenario`` is a :class:`~ovtraj.config.Scenario` or a scenario mapping (the
    YAML's data); its ``target.source_settings`` are used when it has them, else
    ``configs/target_sources.yaml``. ``source`` is a TLE / OMM file (relative to
    ``base_dir``, else the current directory), an http(s) URL (fetched through the
    cache of :mod:`ovtraj.target_sources.fetch`), or a mapping ``{"tle": [...]}`` /
    ``{"omm": {...}}``. The target's name and settings are kept; a flow then runs
    ``scenario_from_dict(scenario_with_target_source(scenario, url))``, and a changed
    element set gives a changed scenario, so a new run id.
    """
    from ovtraj.config.scenario import Scenario

    if isinstance(scenario, Scenario):
        data = scenario.resolved()
    else:
        data = copy.deepcopy(dict(scenario))
    target = {
        k: v
        for k, v in dict(data.get("target") or {}).items()
        if k not in SOURCE_KEYS and k != "catalog_number"
    }
    settings = _settings(target)
    if catalog_number is not None:
        target["catalog_number"] = catalog_number
    if isinstance(source, Mapping):
        target.update(source)
        if any(target.get(k) is not None for k in READ_KEYS):
            target = inline_target(target, base_dir, cache_dir)
    else:
        elements = read_source(
            source,
            settings=settings,
            base_dir=base_dir,
            catalog_number=catalog_number,
            cache_dir=cache_dir,
        )
        target.update(elements.config())
    data["target"] = target
    return data


def fitted_target(scenario: Scenario) -> TargetFit:
    """The fit of the scenario's element set at its epoch (computed once per process)."""
    if not scenario.target.has_source:
        raise ConfigError(["target: hand-typed orbit, nothing to fit"])
    key = json.dumps(
        {
            "target": scenario.target.model_dump(mode="json"),
            "epoch_utc": scenario.epoch_utc,
            "earth": scenario.earth.model_dump(mode="json"),
            "tol": scenario.tolerances.integrator,
        },
        sort_keys=True,
    )
    return _fit_cached(key)


@lru_cache(maxsize=16)
def _fit_cached(key: str) -> TargetFit:
    content = json.loads(key)
    target = TargetConfig.model_validate(content["target"])
    if target.source_settings is None:  # refused by TargetConfig already
        raise ConfigError([f"{_SETTINGS_KEY}: missing"])
    return fit_target(
        target_elements(target),
        Epoch.from_iso(content["epoch_utc"]),
        earth=EarthModel.model_validate(content["earth"]),
        tol=content["tol"],
        settings=target.source_settings,
    )


def _now() -> Epoch:
    return Epoch.from_datetime(datetime.now(UTC).replace(microsecond=0))


def fit_source(
    source: str,
    *,
    epoch_utc: str | None = None,
    span_h: float | None = None,
    catalog_number: int | None = None,
    base_dir: Path | None = None,
    cache_dir: Path | None = None,
) -> TargetFit:
    """What ``ovtraj target SOURCE`` reports: the fit of a TLE / OMM file, a URL or a
    scenario's target.

    A scenario YAML brings its element set, epoch, Earth, integrator tolerance and
    ``target.source_settings``; a file or URL is fitted with
    ``configs/target_sources.yaml``, the Earth and integrator tolerance of the
    shipped ``configs/scenario.yaml``, at the epoch now (UTC, whole seconds).
    ``epoch_utc`` (ISO 8601) and ``span_h`` [h] override. Every bad input is a
    :class:`ConfigError`.
    """
    from ovtraj.config.scenario import load_scenario
    from ovtraj.paths import config_path

    is_scenario = not is_url(source) and Path(source).suffix.lower() in _SCENARIO_SUFFIXES
    if is_scenario:
        if catalog_number is not None:
            raise ConfigError(
                [
                    "--catalog-number applies to a TLE / OMM file or URL; a scenario names "
                    "it in target.catalog_number"
                ],
                source,
            )
        scenario = load_scenario(Path(source))
        if not scenario.target.has_source:
            raise ConfigError(["target: hand-typed orbit, no TLE / OMM / URL to fit"], source)
        elements = target_elements(scenario.target)
        default_epoch = scenario.epoch
    else:
        scenario = load_scenario(config_path("scenario.yaml"))
        default_epoch = None
    settings = scenario.target.source_settings or default_source_settings()
    if span_h is not None:
        update = {**settings.model_dump(), "fit_span_h": span_h}
        settings = model_from_dict(TargetSourceSettings, update, "--span-h")
    if not is_scenario:
        elements = read_source(
            source,
            settings=settings,
            base_dir=base_dir,
            catalog_number=catalog_number,
            cache_dir=cache_dir,
        )
    if epoch_utc is not None:
        try:
            epoch = Epoch.from_iso(epoch_utc)
        except ValueError as err:
            raise ConfigError([str(err)], "--epoch") from None
    else:
        epoch = default_epoch or _now()
    return fit_target(
        elements,
        epoch,
        earth=scenario.earth,
        tol=scenario.tolerances.integrator,
        settings=settings,
    )


def load_scenario_with_target(config: str | Path, target: str | None = None) -> Scenario:
    """The scenario file ``config``, its target replaced by ``target`` when given.

    ``target``: a TLE or OMM file (relative to the current directory) or an http(s)
    URL, as :func:`scenario_with_target_source` reads it. The flows' ``target``
    parameter: a scheduled re-plan from an updated element set with no edit of the
    scenario file.
    """
    from ovtraj.config.scenario import load_scenario, scenario_from_dict

    scenario = load_scenario(config)
    if target is None:
        return scenario
    data = scenario_with_target_source(scenario, target, base_dir=Path.cwd())
    return scenario_from_dict(data, f"{config} (target {target})")
