"""From a scenario's target (or a file, URL or scenario on the command line) to its orbit.

* :func:`load_scenario` reads a scenario file; :func:`inline_target` reads its
  ``tle_file`` / ``omm_file`` / ``url`` target and puts the element set inline (``tle:`` /
  ``omm:``) before validation, which reads nothing;
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
from ovtraj.bounded_reads import read_text_file
from ovtraj.config.base import ConfigError, model_from_dict
from ovtraj.config.io_limits import echoed
from ovtraj.config.target import (
    READ_KEYS,
    SOURCE_KEYS,
    TargetConfig,
    TargetSourceSettings,
    default_source_settings,
)
from ovtraj.element_sets.elements import SourceElements, select_element_set
from ovtraj.element_sets.omm import looks_like_omm, omm_element_sets
from ovtraj.element_sets.tle import tle_element_sets
from ovtraj.target_sources.fetch import fetch_text, is_url

if TYPE_CHECKING:
    from ovtraj.config.scenario import Scenario
    from ovtraj.target_sources.mean_elements_fit import TargetFit

__all__ = [
    "element_sets_from_text",
    "fit_source",
    "fitted_target",
    "inline_target",
    "load_scenario",
    "load_scenario_with_target",
    "read_source",
    "resolved_target",
    "scenario_with_target_source",
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


def resolved_target(
    data: Mapping[str, Any], source_dir: Path | None, cache_dir: Path | None = None
) -> dict[str, Any]:
    """A target mapping ready for validation (:class:`~ovtraj.config.target.TargetConfig`):
    its ``tle_file`` / ``omm_file`` / ``url`` read and put inline (:func:`inline_target`),
    and the shipped ``configs/target_sources.yaml`` as the ``source_settings`` of a real
    element set that names none. A hand-typed orbit, or a mapping without exactly one
    source (validation names the problem), is returned as it is."""
    target = dict(data)
    given = [key for key in SOURCE_KEYS if target.get(key) is not None]
    if len(given) != 1 or given[0] == "orbit":
        return target
    if target.get("source_settings") is None:
        target["source_settings"] = default_source_settings().model_dump()
    if given[0] in READ_KEYS:
        target = inline_target(target, source_dir, cache_dir)
    return target


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario YAML file; its target's file or URL is read here
    (relative files relative to the scenario file's folder) and put inline, so that
    validation reads nothing. :class:`ConfigError` naming the file and field."""
    from ovtraj.config.base import yaml_data
    from ovtraj.config.scenario import scenario_from_dict

    path = Path(path)
    data = yaml_data(path)
    if isinstance(data, dict) and isinstance(data.get("target"), Mapping):
        try:
            target = resolved_target(data["target"], path.resolve().parent)
        except ConfigError as err:
            raise ConfigError([f"target: {p}" for p in err.problems], str(path)) from None
        data = {**data, "target": target}
    return scenario_from_dict(data, str(path))


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
    else:
        elements = read_source(
            source,
            settings=settings,
            base_dir=base_dir,
            catalog_number=catalog_number,
            cache_dir=cache_dir,
        )
        target.update(elements.config())
    data["target"] = resolved_target(target, base_dir, cache_dir)
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
    # Here, not at the top: the fit loads scipy and heyoka (~2 s), which reading a
    # scenario file never needs.
    from ovtraj.target_sources.mean_elements_fit import fit_target

    content = json.loads(key)
    target = TargetConfig.model_validate(content["target"])
    if target.source_settings is None:  # refused by TargetConfig already
        raise ConfigError([f"{_SETTINGS_KEY}: missing"])
    return fit_target(
        target.elements(),
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
    from ovtraj.paths import config_path
    from ovtraj.target_sources.mean_elements_fit import fit_target

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
        elements = scenario.target.elements()
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
    from ovtraj.config.scenario import scenario_from_dict

    scenario = load_scenario(config)
    if target is None:
        return scenario
    data = scenario_with_target_source(scenario, target, base_dir=Path.cwd())
    return scenario_from_dict(data, f"{config} (target {target})")
