"""Strict pydantic base model and readable configuration errors.

Every bounded field declares its allowed range once (``bounded``); a rejected
value is reported as ``target.orbit.eccentricity = 1.2: out of range, allowed
[0, 1)`` rather than as pydantic's generic text.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar, get_args

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from pydantic.fields import FieldInfo

from ovtraj.paths import read_yaml

ModelT = TypeVar("ModelT", bound=BaseModel)


class StrictModel(BaseModel):
    """Unknown keys are errors; values are checked on assignment too."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=True)


def _interval(ge: float | None, gt: float | None, le: float | None, lt: float | None) -> str:
    left = f"[{_fmt(ge)}" if ge is not None else (f"({_fmt(gt)}" if gt is not None else "(-inf")
    right = f"{_fmt(le)}]" if le is not None else (f"{_fmt(lt)})" if lt is not None else "inf)")
    return f"{left}, {right}"


def _fmt(x: float) -> str:
    return f"{x:g}"


def bounded(
    *,
    unit: str = "",
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    description: str = "",
    **kwargs: Any,
) -> Any:
    """A pydantic ``Field`` with numeric bounds and a human-readable allowed range."""
    allowed = _interval(ge, gt, le, lt) + (f" {unit}" if unit else "")
    return Field(
        ge=ge,
        gt=gt,
        le=le,
        lt=lt,
        allow_inf_nan=False,
        description=description,
        json_schema_extra={"allowed": allowed},
        **kwargs,
    )


class ConfigError(ValueError):
    """A configuration that cannot be used, with one line per offending field."""

    def __init__(self, problems: list[str], source: str = "") -> None:
        self.problems = problems
        self.source = source
        head = f"invalid configuration{f' in {source}' if source else ''}:"
        super().__init__("\n".join([head, *(f"  - {p}" for p in problems)]))


def _field_info(model: type[BaseModel], loc: tuple[Any, ...]) -> tuple[FieldInfo | None, list]:
    """Follow an error location through nested models to the field it names."""
    info: FieldInfo | None = None
    current: Any = model
    for part in loc:
        if not (isinstance(current, type) and issubclass(current, BaseModel)):
            return None, []
        info = current.model_fields.get(str(part))
        if info is None:
            return None, sorted(current.model_fields)
        current = _model_in(info.annotation)
    return info, []


def _model_in(annotation: Any) -> Any:
    """The model class inside ``Model | None`` (or the annotation itself)."""
    for member in get_args(annotation) or (annotation,):
        if isinstance(member, type) and issubclass(member, BaseModel):
            return member
    return annotation


def _allowed(info: FieldInfo | None) -> str | None:
    extra = info.json_schema_extra if info is not None else None
    return extra.get("allowed") if isinstance(extra, dict) else None


def format_validation_error(err: ValidationError, model: type[BaseModel]) -> list[str]:
    """Turn pydantic's errors into one readable line each."""
    lines = []
    for item in err.errors():
        loc = tuple(item["loc"])
        path = ".".join(str(p) for p in loc) or "<root>"
        kind = item["type"]
        value = item.get("input")
        if kind == "extra_forbidden":
            parent_info, siblings = _field_info(model, loc[:-1]) if len(loc) > 1 else (None, [])
            parent = _model_in(parent_info.annotation) if parent_info is not None else model
            if isinstance(parent, type) and issubclass(parent, BaseModel):
                siblings = sorted(parent.model_fields)
            lines.append(f"{path}: unknown key (allowed keys: {', '.join(siblings)})")
            continue
        if kind == "missing":
            lines.append(f"{path}: required key is missing")
            continue
        info, _ = _field_info(model, loc)
        allowed = _allowed(info)
        if allowed and kind in {
            "greater_than",
            "greater_than_equal",
            "less_than",
            "less_than_equal",
            "finite_number",
        }:
            lines.append(f"{path} = {value!r}: out of range, allowed {allowed}")
            continue
        msg = item["msg"].removeprefix("Value error, ")
        suffix = f" (allowed {allowed})" if allowed else ""
        if not loc:
            lines.append(msg)
        elif value is None or isinstance(value, dict):
            lines.append(f"{path}: {msg}")
        else:
            lines.append(f"{path} = {value!r}: {msg}{suffix}")
    return lines


def model_from_dict(model: type[ModelT], data: Any, source: str = "") -> ModelT:
    """Validate a mapping into ``model``, raising :class:`ConfigError` (one line per field)."""
    if not isinstance(data, dict):
        raise ConfigError(
            [f"expected a mapping at the top level, got {type(data).__name__}"], source
        )
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise ConfigError(format_validation_error(err, model), source) from None


def load_model(model: type[ModelT], path: str | Path) -> ModelT:
    """Read a YAML file and validate it into ``model``; every failure is a ConfigError."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError([f"cannot read the file: {err.strerror}"], str(path)) from None
    try:
        data = read_yaml(text)
    except yaml.YAMLError as err:
        raise ConfigError([f"not valid YAML: {err}"], str(path)) from None
    return model_from_dict(model, data, str(path))
