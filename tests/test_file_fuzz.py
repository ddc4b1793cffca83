"""Every command that reads a JSON, YAML, TLE, OMM or Parquet file, fed hostile files.

The files: arrays and mappings nested 10^5 deep, numbers of 5,000 digits, NaN, inf, zero
and negative physical values (a mass, a payload, a mean motion, an eccentricity), wrong
types and truncated files, each made from a well-formed file of its kind (a mission plan
built here, the shipped scenario and settings, the shipped test TLE and OMMs, a stored
run). Each case must end with exit code 2 (bad input) and nothing on stdout, its stderr
one line (or, for a file with several faults, one line naming the file and a line per
fault under it: ``ConfigError``'s form); never an internal error, a traceback or a hang,
and nothing written outside the workspace.

A stored run's Parquet and JSON files are replaced by hostile ones whose digests the
manifest records (a store without a key trusts its manifests): `show` and `replay` refuse
them in one line or do not read them, and `verify` reports (exit 0 or 1, never a fault).

The commands run in this process through :func:`ovtraj.cli.run_command` (as in
tests/test_cli_fuzz.py), each under an alarm that ends a case that hangs, failing the test
and not the suite. Commands sharing a reader (a scenario's, an element set's, a plan's)
get every variant through one of them and a few through the others, which keeps the file
under 30 s.
"""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest
import yaml

from ovtraj.cli import run_command
from ovtraj.paths import config_path
from tests.conftest import DEFAULT_SCENARIO, REPO

TARGETS = REPO / "tests" / "data" / "targets"
ISS_TLE = TARGETS / "iss_2019-12-09.tle"
DEEP = 100_000  # levels of nesting
DIGITS = "9" * 5000  # a number of 5,000 digits
# The variants also given to the commands that share a reader with one fed every variant.
SHARED_READER_CASES = {
    "nested arrays",
    "5000-digit float",
    "NaN payload",
    "zero payload",
    "not UTF-8",
    "nested flow sequences",
    "truncated",
    "zero vehicle.mass_kg",
    "5000 digits vehicle.mass_kg",
    "NaN vehicle.isp_s",
    "TLE mean motion 0.00000000",
    "OMM JSON nested",
    "OMM JSON MEAN_MOTION 0",
    "OMM KVN ECCENTRICITY 1.5",
}
CASE_LIMIT_S = 30  # a refused case takes ~10-100 ms here; a hang is what this catches


class _Hung(BaseException):
    """Raised by the alarm (a BaseException: the CLI turns every Exception into a line)."""


def _hung(signum, frame) -> None:
    raise _Hung


def _run(args: list[str]) -> int | None:
    signal.alarm(CASE_LIMIT_S)
    try:
        return run_command(list(args))
    except _Hung:
        return None
    finally:
        signal.alarm(0)


@pytest.fixture(scope="module")
def plan_data(reference_plan_file) -> dict:
    """A well-formed mission plan (as its JSON file holds it)."""
    return json.loads(reference_plan_file.read_text())


@pytest.fixture
def workspace(tmp_path, monkeypatch):
    ws = tmp_path / "ws"
    for name in ("home", "store", "cwd", "in"):
        (ws / name).mkdir(parents=True)
    monkeypatch.setenv("OVTRAJ_HOME", str(ws / "home"))
    monkeypatch.chdir(ws / "cwd")
    return ws


def _nested(kind: str) -> str:
    """JSON (also YAML flow) text nested :data:`DEEP` levels."""
    return "[" * DEEP + "]" * DEEP if kind == "array" else '{"a":' * DEEP + "1" + "}" * DEEP


def _set(data: dict, path: tuple, value) -> dict:
    copy = json.loads(json.dumps(data))
    node = copy
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return copy


def _json_variants(data: dict) -> dict[str, str]:
    """Hostile JSON texts around the well-formed document ``data``."""
    text = json.dumps(data, indent=1)
    payload = ("launch", "payload_kg")
    return {
        "nested arrays": _nested("array"),
        "nested objects": _nested("object"),
        "5000-digit version": '{"schema_version": ' + DIGITS + "}",
        "5000-digit payload": json.dumps(_set(data, payload, 1)).replace(
            '"payload_kg": 1', f'"payload_kg": {DIGITS}'
        ),
        "5000-digit float": json.dumps(_set(data, payload, 1)).replace(
            '"payload_kg": 1', f'"payload_kg": 0.{DIGITS}e{DIGITS}'
        ),
        "NaN payload": json.dumps(_set(data, payload, float("nan"))),
        "inf payload": json.dumps(_set(data, payload, float("inf"))),
        "1e999 payload": json.dumps(_set(data, payload, 1)).replace(
            '"payload_kg": 1', '"payload_kg": 1e999'
        ),
        "zero payload": json.dumps(_set(data, payload, 0.0)),
        "negative payload": json.dumps(_set(data, payload, -400.0)),
        "zero mass": json.dumps(_set(data, ("scenario", "vehicle", "mass_kg"), 0.0)),
        "negative stated miss": json.dumps(_set(data, ("terminal", "stated_miss_m"), -1.0)),
        "string payload": json.dumps(_set(data, payload, "heavy")),
        "list at the top": "[1, 2]",
        "design as a list": json.dumps(_set(data, ("design",), [1, 2, 3])),
        "truncated": text[: len(text) // 2],
        "empty": "",
        "not UTF-8": "\udcff",
    }


def _yaml_variants(data: dict, physical: list[tuple[tuple, bool]]) -> dict[str, str]:
    """Hostile YAML texts around the well-formed mapping ``data``; ``physical``: paths of
    numbers given negative, NaN, inf, 5,000 digits and (unless zero is allowed there) zero."""
    text = yaml.safe_dump(data, sort_keys=False)
    variants = {
        "nested flow sequences": _nested("array"),
        "nested flow mappings": _nested("object"),
        # block nesting as deep as fits in a config file (the read is capped at 1 MiB)
        "nested blocks": "".join(f"{' ' * k}a:\n" for k in range(1400)) + " " * 1400 + "b: 1\n",
        "a list at the top": "- 1\n- 2\n",
        "a number at the top": DIGITS + "\n",
        "truncated": text[: len(text) // 2],
        "empty": "",
    }
    for path, zero_allowed in physical:
        name = ".".join(path)
        values = [("negative", -1), ("NaN", ".nan"), ("inf", ".inf"), ("5000 digits", DIGITS)]
        values += [("a list", "[1, 2]")] + ([] if zero_allowed else [("zero", 0)])
        for label, value in values:
            variants[f"{label} {name}"] = _yaml_value(data, path, value)
    return variants


def _yaml_value(data: dict, path: tuple, value) -> str:
    """The YAML of ``data`` with the value at ``path`` written as the text ``value``."""
    marker = "__fuzzed__"
    text = yaml.safe_dump(_set(data, path, marker), sort_keys=False)
    return text.replace(marker, str(value))


def _tle(mean_motion: str = "15.50103472", name: str = "ISS") -> str:
    """The ISS TLE with line 2's mean motion (columns 53-63) replaced, checksums right."""
    line1, line2 = ISS_TLE.read_text().splitlines()[1:3]
    line2 = line2[:52] + mean_motion.rjust(11)[:11] + line2[63:68]
    lines = [line1[:68], line2]
    return "\n".join([name, *(line + _checksum(line) for line in lines)]) + "\n"


def _checksum(line: str) -> str:
    return str(sum(int(c) if c.isdigit() else c == "-" for c in line[:68]) % 10)


def _element_set_variants() -> dict[str, str]:
    omm = json.loads((TARGETS / "mario_2023-04-25.json").read_text())
    record = omm[0] if isinstance(omm, list) else omm
    kvn = (TARGETS / "mario_2023-04-25.kvn").read_text()
    csv = (TARGETS / "mario_2023-04-25.csv").read_text()
    xml = (TARGETS / "mario_2023-04-25.xml").read_text()
    variants = {
        f"TLE mean motion {value}": _tle(value)
        for value in ("0.00000000", "-1.0000000", "nan", "inf", "-inf")
    }
    variants |= {
        "TLE one line": ISS_TLE.read_text().splitlines()[1] + "\n",
        "TLE truncated": ISS_TLE.read_text()[:100],
        "TLE 5000 digits": "1 " + DIGITS + "\n2 " + DIGITS + "\n",
        "OMM JSON nested": _nested("array"),
        "OMM JSON nested objects": _nested("object"),
        "OMM JSON 5000 digits": json.dumps(record).replace(
            f'"NORAD_CAT_ID": {json.dumps(record["NORAD_CAT_ID"])}', f'"NORAD_CAT_ID": {DIGITS}'
        ),
        "OMM JSON truncated": json.dumps(record)[:200],
        "OMM JSON wrong type": json.dumps({**record, "MEAN_MOTION": [1, 2]}),
        "OMM JSON a number": "[1]",
        "OMM XML nested": "<a>" * DEEP + "</a>" * DEEP,
        "OMM XML truncated": xml[: len(xml) // 2],
        "OMM KVN truncated": kvn[: len(kvn) // 3],
        "OMM CSV truncated": csv[: len(csv) // 2],
    }
    for field, values in {
        "MEAN_MOTION": ("0", "-1", "NaN", "inf", DIGITS),
        "ECCENTRICITY": ("1", "1.5", "-0.1", "NaN"),
        "INCLINATION": ("NaN", "inf"),
    }.items():
        for value in values:
            shown = value if len(value) < 10 else "5000 digits"
            variants[f"OMM JSON {field} {shown}"] = json.dumps({**record, field: value})
            variants[f"OMM KVN {field} {shown}"] = _kvn_value(kvn, field, value)
    # CSV and XML values are read by the same field checks as KVN's (text to number)
    variants["OMM CSV MEAN_MOTION 0"] = _csv_value(csv, "MEAN_MOTION", "0")
    variants["OMM CSV ECCENTRICITY NaN"] = _csv_value(csv, "ECCENTRICITY", "NaN")
    return variants


def _kvn_value(kvn: str, field: str, value: str) -> str:
    lines = [
        f"{field} = {value}" if line.split("=")[0].strip() == field else line
        for line in kvn.splitlines()
    ]
    return "\n".join(lines) + "\n"


def _csv_value(csv: str, field: str, value: str) -> str:
    header, *rows = csv.strip().splitlines()
    names = header.split(",")
    cells = rows[0].split(",")
    cells[names.index(field)] = value
    return "\n".join([header, ",".join(cells)]) + "\n"


def _write(folder: Path, stem: str, suffix: str, text: str) -> Path:
    safe = "".join(c if c.isalnum() else "-" for c in stem)
    path = folder / f"{safe}{suffix}"
    path.write_text(text, encoding="utf-8", errors="surrogateescape")
    return path


def _cases(ws: Path, plan_data: dict) -> list[list[str]]:
    into = ws / "in"
    store = ["--store", str(ws / "store")]
    cases: list[list[str]] = []
    for stem, text in _json_variants(plan_data).items():
        for suffix in (".json",):
            plan = _write(into, f"plan {stem}", suffix, text)
            cases += [
                ["fly", str(plan)],
                ["export", str(plan), "--format", "opm", "--out", str(ws / "x.opm")],
            ]
            if stem in SHARED_READER_CASES:  # the same plan reader as fly and export
                cases += [["lineage", str(plan), *store], ["diff", str(plan), str(plan), *store]]
    plan_yaml = yaml.safe_dump(plan_data, sort_keys=False)
    for stem, text in {
        "nested": _nested("array"),
        "truncated": plan_yaml[: len(plan_yaml) // 2],
        "zero payload": _yaml_value(plan_data, ("launch", "payload_kg"), 0),
        "NaN payload": _yaml_value(plan_data, ("launch", "payload_kg"), ".nan"),
        "5000-digit payload": _yaml_value(plan_data, ("launch", "payload_kg"), DIGITS),
    }.items():
        plan = _write(into, f"plan yaml {stem}", ".yaml", text)
        cases += [["fly", str(plan)], ["diff", str(plan), str(plan), *store]]

    good_plan = _write(into, "good plan", ".json", json.dumps(plan_data))
    scenario = yaml.safe_load(DEFAULT_SCENARIO.read_text())
    physical = [
        (("vehicle", "mass_kg"), False),
        (("vehicle", "isp_s"), False),
        (("parking_orbit", "altitude_km"), False),
    ]
    # every variant through the scenario loader of `run` and of a stage; the other commands
    # that read a scenario share that loader, so a few variants each
    for stem, text in _yaml_variants(scenario, physical).items():
        path = _write(into, f"scenario {stem}", ".yaml", text)
        cases += [["run", str(path), "--samples", "2", *store], ["rendezvous", str(path)]]
        if stem in SHARED_READER_CASES:
            cases += [
                ["pipeline", str(path), *store],
                ["window", str(path), "--days", "2", *store],
                ["target", str(path)],
            ]
    settings = {
        "dispersions": (config_path("dispersions.yaml"), [(("burns", "pointing_deg"), True)]),
        "force model": (config_path("force_model.yaml"), []),
        "export": (config_path("ccsds_export.yaml"), [(("orbit_step_s",), False)]),
    }
    for kind, (shipped, fields) in settings.items():
        for stem, text in _yaml_variants(yaml.safe_load(shipped.read_text()), fields).items():
            path = _write(into, f"{kind} {stem}", ".yaml", text)
            cases.append(
                {
                    "dispersions": ["fly", str(good_plan), "--monte-carlo", "1"],
                    "force model": ["fly", str(good_plan), "--fidelity", "high"],
                    "export": ["export", str(good_plan), "--format", "opm"],
                }[kind]
                + {
                    "dispersions": ["--dispersions", str(path)],
                    "force model": ["--force-model", str(path)],
                    "export": ["--settings", str(path), "--out", str(ws / "y.opm")],
                }[kind]
            )
    for stem, text in _element_set_variants().items():
        suffix = ".tle" if stem.startswith("TLE") else ".txt"
        path = _write(into, f"elements {stem}", suffix, text)
        cases.append(["target", str(path)])
        if stem in SHARED_READER_CASES:  # the same element-set reader as `target`
            cases += [
                ["run", "--target", str(path), "--samples", "2", *store],
                ["window", "--days", "2", "--target", str(path), *store],
            ]
    cases += [["runs", "--store", "s3://"], ["run", "--store", "s3://"]]
    return cases


def _one_message(err: str) -> bool:
    """One line; or, for a file with several faults, one line naming the file and a line
    per fault under it (``ConfigError``'s and the plan reader's form). Never a traceback."""
    lines = err.splitlines()
    if not lines or "Traceback" in err or "internal error" in err:
        return False
    return len(lines) == 1 or (
        lines[0].endswith(":") and all(line.startswith("  - ") for line in lines[1:])
    )


def test_hostile_files_end_in_one_line_exit_2(workspace, plan_data, tmp_path, capsys):
    before = {p for p in tmp_path.rglob("*") if workspace not in (p, *p.parents)}
    cases = _cases(workspace, plan_data)
    failures = []
    previous = signal.signal(signal.SIGALRM, _hung)
    try:
        for args in cases:
            code = _run(args)
            out, err = capsys.readouterr()
            if code != 2 or out or not _one_message(err):
                shown = [a if len(a) < 120 else a[:60] + "..." for a in args]
                failures.append(f"{shown!r}: exit {code}, stdout {out[:200]!r}, {err[:400]!r}")
    finally:
        signal.signal(signal.SIGALRM, previous)
    assert not failures, f"{len(failures)} of {len(cases)} cases:\n" + "\n".join(failures)
    after = {p for p in tmp_path.rglob("*") if workspace not in (p, *p.parents)}
    assert after == before  # nothing written outside the workspace
    # every case refused before it wrote (the catalog's folder: lineage and diff look there)
    assert [p.name for p in (workspace / "store").iterdir()] in ([], ["catalog"])
    assert os.listdir(workspace / "cwd") == []


# --------------------------------------------------------------------------- #
# A stored run's files, hostile and recorded as they are (a store without a key)
# --------------------------------------------------------------------------- #
@pytest.fixture(scope="module")
def stored_run(tmp_path_factory) -> Path:
    store = tmp_path_factory.mktemp("stored") / "store"
    assert run_command(["run", "--samples", "2", "--store", str(store)]) == 0
    (run,) = [p for p in store.iterdir() if p.name != "catalog"]
    return run


def _parquet_variants(original: bytes) -> dict[str, bytes]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    other = pa.BufferOutputStream()
    pq.write_table(pa.table({"x": [1.0, float("nan"), float("inf")]}), other)
    deep = pa.BufferOutputStream()  # a column of lists nested 64 deep
    value: object = [1.0]
    for _ in range(63):
        value = [value]
    pq.write_table(pa.table({"deep": [value]}), deep)
    return {
        "truncated": original[: len(original) // 2],
        "not Parquet": b"PAR1" + b"\x00" * 100 + b"PAR1",
        "empty": b"",
        "other columns": other.getvalue().to_pybytes(),
        "nested columns": deep.getvalue().to_pybytes(),
    }


def _stored_json_variants() -> dict[str, bytes]:
    return {
        "nested arrays": _nested("array").encode(),
        "nested objects": _nested("object").encode(),
        "5000-digit number": ('{"seed": ' + DIGITS + "}").encode(),
        "a list": b"[1, 2]",
        "truncated": b'{"name": "iss',
    }


def _recorded(run: Path, name: str, payload: bytes) -> None:
    """``name`` of ``run`` holds ``payload``, its manifest records it (a forger without
    the store key)."""
    from ovtraj.store.files import Digest

    (run / name).write_bytes(payload)
    manifest = json.loads((run / "manifest.json").read_text())
    manifest["files"][name] = Digest.of(payload).to_json()
    (run / "manifest.json").write_text(json.dumps(manifest))


def test_hostile_stored_files_recorded_as_they_are_end_in_one_line(
    stored_run, workspace, tmp_path, capsys
):
    import shutil

    variants = [
        ("samples.parquet", stem, payload)
        for stem, payload in _parquet_variants(
            (stored_run / "samples.parquet").read_bytes()
        ).items()
    ] + [("config.json", stem, payload) for stem, payload in _stored_json_variants().items()]
    failures = []
    previous = signal.signal(signal.SIGALRM, _hung)
    try:
        for k, (name, stem, payload) in enumerate(variants):
            store = workspace / f"store{k}"
            run = store / stored_run.name
            shutil.copytree(stored_run, run)
            _recorded(run, name, payload)
            for command in ("show", "replay", "verify"):
                code = _run([command, run.name, "--store", str(store)])
                out, err = capsys.readouterr()
                bad = "Traceback" in err or "internal error" in err or code is None
                if command == "verify":  # checks digests and schemas: its report on stdout
                    bad = bad or code not in (0, 1)
                elif code != 0:
                    bad = bad or code != 2 or out or not _one_message(err)
                if bad:
                    failures.append(
                        f"{command} {name} {stem}: exit {code}, {out[:200]!r}, {err[:300]!r}"
                    )
    finally:
        signal.signal(signal.SIGALRM, previous)
    assert not failures, "\n".join(failures)
