"""A mission plan stored as files and read back (SPEC step 6).

:func:`write_plan` stores a plan as JSON and YAML (:func:`plan_json`, :func:`plan_yaml`),
never replacing a different stored plan; :func:`read_plan` reads either back, naming the
file and the field on bad content, and checks the plan's scenario as a scenario file is.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from ovtraj.config.base import ConfigError, format_validation_error, parse_yaml
from ovtraj.config.io_limits import echoed, read_config_file
from ovtraj.formatting import printable
from ovtraj.mission.plan import SCHEMA_VERSION, MissionPlan, PlanError
from ovtraj.store.backends import location
from ovtraj.store.files import StoreError, holds_other, json_data, write_bytes


def plan_json(plan: MissionPlan) -> bytes:
    """The plan as JSON text (UTF-8), keys in schema order."""
    return (json.dumps(plan.to_dict(), indent=2, allow_nan=False) + "\n").encode("utf-8")


class _WrittenOut(yaml.SafeDumper):
    """Every value written where it is: :func:`read_plan` refuses anchors and aliases
    (:func:`ovtraj.bounded_reads.read_yaml`), which PyYAML writes for an object met twice."""

    def ignore_aliases(self, data: Any) -> bool:
        return True


def plan_yaml(plan: MissionPlan) -> bytes:
    """The plan as YAML text (UTF-8), keys in schema order; floats round-trip exactly."""
    text = yaml.dump(
        plan.to_dict(), Dumper=_WrittenOut, sort_keys=False, allow_unicode=True, width=100
    )
    return text.encode("utf-8")


def write_plan(plan: MissionPlan, directory: Path, name: str) -> tuple[Path, Path]:
    """Write ``<name>.json`` and ``<name>.yaml`` in ``directory`` atomically.

    An existing file with the same content is left as it is; one with different
    content raises :class:`PlanError` and neither file is touched (a stored plan is
    never replaced by another).
    """
    if not name or Path(name).name != name or name in {".", ".."}:
        raise PlanError(f"plan name {name!r} must be a plain file name")
    directory = location(directory)
    targets = (
        (directory / f"{name}.json", plan_json(plan)),
        (directory / f"{name}.yaml", plan_yaml(plan)),
    )
    for path, payload in targets:
        try:  # a file already there is read as a stored file (no FIFO, device or link)
            other = holds_other(path, payload)
        except StoreError as err:
            raise PlanError(str(err)) from None
        if other:
            raise PlanError(
                f"{path}: a different plan is stored there; refusing to overwrite it "
                "(choose another name or directory)"
            )
    for path, payload in targets:
        write_bytes(path, payload)
    return targets[0][0], targets[1][0]


def read_plan(path: Path) -> MissionPlan:
    """A plan from its JSON or YAML file; :class:`PlanError` names the file and the field."""
    path = Path(path)
    shown = printable(str(path))
    suffix = path.suffix.lower()
    if suffix not in {".json", ".yaml", ".yml"}:
        raise PlanError(f"{shown}: a plan file ends in .json, .yaml or .yml")
    try:  # a regular file within config_file_max_kib (configs/io_limits.yaml)
        text = read_config_file(path)
    except ConfigError as err:
        raise PlanError(f"{shown}: cannot read the plan file ({'; '.join(err.problems)})") from None
    try:  # both bounded: depth and numbers (json_data), anchors and aliases (parse_yaml)
        data = json_data(text) if suffix == ".json" else parse_yaml(text)
    except ValueError as err:  # one line
        raise PlanError(f"{shown}: {err}") from None
    if not isinstance(data, dict):
        raise PlanError(f"{shown}: expected a mapping at the top level, got {type(data).__name__}")
    version = data.get("schema_version")
    if version != SCHEMA_VERSION:
        raise PlanError(
            f"{shown}: schema_version = {echoed(repr(version))}: this code reads "
            f"{SCHEMA_VERSION!r} plans"
        )
    try:
        plan = MissionPlan.model_validate(data)
    except ValidationError as err:
        problems = format_validation_error(err, MissionPlan)
        if len(problems) == 1:  # one line, as ConfigError has it
            raise PlanError(f"{shown}: invalid mission plan: {problems[0]}") from None
        raise PlanError(
            "\n".join([f"{shown}: invalid mission plan:", *(f"  - {p}" for p in problems)])
        ) from None
    # the scenario the plan is flown in, checked as a scenario file is (bad input named
    # here, not a flight that fails later)
    from ovtraj.config import scenario_from_dict

    try:
        scenario_from_dict(plan.scenario, f"{shown}: scenario")
    except ConfigError as err:
        raise PlanError(str(err)) from None
    return plan
