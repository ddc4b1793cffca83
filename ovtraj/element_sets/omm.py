"""CCSDS Orbit Mean-Elements Messages (OMM) with SGP4 elements: XML, KVN, JSON, CSV.

The formats (CCSDS 502.0-B-3, "Orbit Data Messages"): XML (the NDM/XML schema:
``segment/metadata``, ``segment/data/meanElements``, ``segment/data/tleParameters``,
read as ``sgp4.omm.parse_xml`` reads it, with a missing part named), KVN
(``KEY = value [unit]`` lines, ``COMMENT`` lines skipped, one message per
``CCSDS_OMM_VERS``), and CelesTrak's JSON (a list of records with the same field
names) and CSV (a header of field names; ``sgp4.omm.parse_csv``). Every record
must hold the fields ``sgp4.omm.initialize`` reads; a record that states its mean
element theory, frame, time system or centre must state SGP4, TEME, UTC, EARTH
(SGP4-XP or DSST mean elements are not SGP4's and would give another orbit).
"""

from __future__ import annotations

import csv
import io
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from datetime import datetime
from typing import Any

from sgp4 import omm as sgp4_omm
from sgp4.api import WGS72, Satrec

from ovtraj.astro.epoch import Epoch
from ovtraj.element_sets.elements import SourceElements, check_physical, checked_satrec
from ovtraj.errors import ConfigError
from ovtraj.store.files import json_data

__all__ = ["looks_like_omm", "omm_element_sets", "omm_elements"]

# The fields sgp4.omm.initialize reads (sgp4 2.x), all required.
REQUIRED_FIELDS = (
    "OBJECT_ID",
    "EPOCH",
    "MEAN_MOTION",
    "ECCENTRICITY",
    "INCLINATION",
    "RA_OF_ASC_NODE",
    "ARG_OF_PERICENTER",
    "MEAN_ANOMALY",
    "EPHEMERIS_TYPE",
    "CLASSIFICATION_TYPE",
    "NORAD_CAT_ID",
    "ELEMENT_SET_NO",
    "REV_AT_EPOCH",
    "BSTAR",
    "MEAN_MOTION_DOT",
    "MEAN_MOTION_DDOT",
)
_REAL_FIELDS = (
    "MEAN_MOTION",
    "ECCENTRICITY",
    "INCLINATION",
    "RA_OF_ASC_NODE",
    "ARG_OF_PERICENTER",
    "MEAN_ANOMALY",
    "BSTAR",
    "MEAN_MOTION_DOT",
    "MEAN_MOTION_DDOT",
)
_INTEGER_FIELDS = ("EPHEMERIS_TYPE", "NORAD_CAT_ID", "ELEMENT_SET_NO", "REV_AT_EPOCH")
# What a record may state about itself, and the values SGP4 elements have.
_STATED = {
    "MEAN_ELEMENT_THEORY": ("SGP4", "SGP/SGP4"),
    "REF_FRAME": ("TEME",),
    "TIME_SYSTEM": ("UTC",),
    "CENTER_NAME": ("EARTH",),
}
_KVN_UNITS = re.compile(r"\s*\[[^\]]*\]\s*$")
# sgp4.omm.initialize reads EPOCH with this format (microseconds required).
_SGP4_EPOCH_FORMAT = "%Y-%m-%dT%H:%M:%S.%f"
_FRACTION = re.compile(r"(\.\d{1,6})\d*")


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _epoch_text(value: Any, where: str, label: str) -> str:
    """EPOCH as ``sgp4.omm`` reads it; CCSDS allows ``YYYY-DDDThh:mm:ss`` and no fraction."""
    text = str(value).strip().removesuffix("Z")
    text = _FRACTION.sub(r"\1", text, count=1)  # datetime keeps microseconds
    for fmt in ("%Y-%m-%dT%H:%M:%S.%f", "%Y-%m-%dT%H:%M:%S", "%Y-%jT%H:%M:%S.%f", "%Y-%jT%H:%M:%S"):
        try:
            return datetime.strptime(text, fmt).strftime(_SGP4_EPOCH_FORMAT)
        except ValueError:
            continue
    raise ConfigError([f"{label}: EPOCH = {value!r} is not a CCSDS date-time"], where)


def omm_elements(fields: Mapping[str, Any], where: str, label: str = "OMM") -> SourceElements:
    """One element set from an OMM record's fields (values as text or numbers).

    Raises :class:`ConfigError` naming the field that is missing, does not parse or
    states another theory, frame, time system or centre.
    """
    record = {str(k): v for k, v in fields.items() if v is not None}
    missing = [f for f in REQUIRED_FIELDS if record.get(f) in (None, "")]
    if missing:
        raise ConfigError([f"{label}: missing field {', '.join(missing)}"], where)
    for key, allowed in _STATED.items():
        value = record.get(key)
        if value not in (None, "") and str(value).strip().upper() not in allowed:
            raise ConfigError(
                [f"{label}: {key} = {value!r}; SGP4 elements need {' or '.join(allowed)}"], where
            )
    for key in _REAL_FIELDS:
        try:
            float(record[key])
        except (TypeError, ValueError):
            raise ConfigError(
                [f"{label}: {key} = {record[key]!r} is not a number"], where
            ) from None
    check_physical({key: float(record[key]) for key in _REAL_FIELDS}, where, label)
    for key in _INTEGER_FIELDS:
        try:
            int(record[key])
        except (TypeError, ValueError):
            raise ConfigError(
                [f"{label}: {key} = {record[key]!r} is not an integer"], where
            ) from None
    sgp4_fields = {k: str(v) if isinstance(v, str) else v for k, v in record.items()}
    sgp4_fields["EPOCH"] = _epoch_text(record["EPOCH"], where, label)
    sgp4_fields["OBJECT_ID"] = str(record["OBJECT_ID"])
    sgp4_fields["CLASSIFICATION_TYPE"] = str(record["CLASSIFICATION_TYPE"])
    sat = Satrec()
    sgp4_omm.initialize(sat, sgp4_fields, WGS72)
    checked_satrec(sat, where, label)
    return SourceElements(
        kind="omm",
        record=tuple(record.items()),
        name=str(record.get("OBJECT_NAME", "") or "").strip(),
        catalog_number=int(record["NORAD_CAT_ID"]),
        epoch=Epoch(sat.jdsatepoch, sat.jdsatepochF),
        satrec=sat,
        where=where,
    )


def _xml_records(text: str, where: str) -> list[dict[str, Any]]:
    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise ConfigError([f"OMM XML is not well-formed: {err}"], where) from None
    segments = [el for el in root.iter() if _local(el.tag) == "segment"]
    records = []
    for k, segment in enumerate(segments, 1):
        fields: dict[str, Any] = {}
        for path in (("metadata",), ("data", "meanElements"), ("data", "tleParameters")):
            node: ET.Element | None = segment
            for part in path:
                node = next((c for c in node if _local(c.tag) == part), None)
                if node is None:
                    raise ConfigError(
                        [f"OMM XML segment {k}: no <{'/'.join(path)}> element"], where
                    )
            fields.update((_local(child.tag), (child.text or "").strip()) for child in node)
        records.append(fields)
    return records


def _kvn_records(text: str, where: str) -> list[dict[str, Any]]:
    records: list[dict[str, Any]] = []
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("COMMENT"):
            continue
        key, sep, value = line.partition("=")
        if not sep:
            raise ConfigError([f"OMM KVN line {n}: expected 'KEY = value'"], where)
        key = key.strip()
        if key == "CCSDS_OMM_VERS" or not records:
            records.append({})
        records[-1][key] = _KVN_UNITS.sub("", value).strip()
    return records


def _json_records(text: str, where: str) -> list[dict[str, Any]]:
    try:  # bounded: nesting depth and number length (configs/io_limits.yaml)
        data = json_data(text)
    except ValueError as err:
        raise ConfigError([f"OMM JSON: {err}"], where) from None
    items = data if isinstance(data, list) else [data]
    if not all(isinstance(item, dict) for item in items):
        raise ConfigError(["OMM JSON: expected an object or a list of objects"], where)
    return items


def _csv_records(text: str, where: str) -> list[dict[str, Any]]:
    try:
        rows = list(sgp4_omm.parse_csv(io.StringIO(text)))
    except csv.Error as err:
        raise ConfigError([f"OMM CSV does not parse: {err}"], where) from None
    return [{k: v for k, v in row.items() if k is not None} for row in rows]


def _kind(text: str) -> str | None:
    head = text.lstrip("\ufeff \t\r\n")
    first = head.split("\n", 1)[0]
    if head.startswith("<"):
        return "XML"
    if head.startswith(("[", "{")):
        return "JSON"
    if first.replace(" ", "").startswith("CCSDS_OMM_VERS="):
        return "KVN"
    if "," in first and "EPOCH" in first.upper():
        return "CSV"
    return None


def looks_like_omm(text: str) -> bool:
    """Whether ``text`` is an OMM (XML, JSON, KVN or CSV) rather than a TLE."""
    return _kind(text) is not None


def omm_element_sets(text: str, where: str) -> list[SourceElements]:
    """Every element set of an OMM text, whichever of the four encodings it is in."""
    kind = _kind(text)
    readers = {"XML": _xml_records, "KVN": _kvn_records, "JSON": _json_records, "CSV": _csv_records}
    if kind is None:
        raise ConfigError(["not an OMM in XML, KVN, JSON or CSV"], where)
    records = readers[kind](text.lstrip("\ufeff"), where)
    many = len(records) > 1
    return [
        omm_elements(fields, where, f"OMM {kind} record {k}" if many else f"OMM {kind}")
        for k, fields in enumerate(records, 1)
    ]
