"""Strict pydantic base model and readable configuration errors.

Every bounded field declares its allowed range once (``bounded``); a rejected
value is reported as ``target.orbit.eccentricity = 1.2: out of range, allowed
[0, 1)`` rather than as pydantic's generic text.

pydantic's lax mode turns ``true`` into 1 wherever a number goes (``bool`` is a
subclass of ``int``). Its strict mode would refuse that, but it also refuses a YAML
list for a tuple field and the string YAML 1.1 makes of ``1e30``, so
:class:`StrictModel` keeps lax mode and refuses booleans alone, in one validator that
runs before every field whose type holds numbers (also inside ``| None``, lists and
tuples) and no ``bool``: ``initial.longitude_deg = True: expected a number, not a
boolean``.
"""

from __future__ import annotations

import datetime
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal, TypeVar, get_args, get_origin

import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
)
from pydantic.fields import FieldInfo
from pydantic_core import PydanticCustomError

from ovtraj.bounded_reads import read_yaml
from ovtraj.errors import ConfigError

ModelT = TypeVar("ModelT", bound=BaseModel)


BOOL_NOT_NUMBER = "bool_not_number"


def _leaf_types(annotation: Any) -> set[Any]:
    """The types a value (or an item of it) may take: ``list[float] | None`` -> {float, None}."""
    origin = get_origin(annotation)
    if origin is Annotated:
        return _leaf_types(get_args(annotation)[0])
    if origin is Literal:
        return {type(arg) for arg in get_args(annotation)}
    args = [a for a in get_args(annotation) if a is not Ellipsis]
    if not args:
        return {annotation}
    return set().union(*(_leaf_types(a) for a in args))


def _numbers_only(annotation: Any) -> bool:
    """A field that holds numbers (``int``/``float``, maybe nested) and never a ``bool``."""
    leaves = _leaf_types(annotation)
    return bool(leaves & {int, float}) and bool not in leaves


def _holds_bool(value: Any) -> bool:
    if isinstance(value, bool):
        return True
    return isinstance(value, (list, tuple)) and any(_holds_bool(v) for v in value)


class StrictModel(BaseModel):
    """Unknown keys are errors; values are checked on assignment too; a bool is not a number."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=True)

    # Fields whose type holds numbers and no bool; and, for fields holding a plain pydantic
    # model (not a StrictModel, e.g. the Earth model), that model's such fields.
    _numeric_fields: ClassVar[frozenset[str]] = frozenset()
    _plain_model_fields: ClassVar[dict[str, frozenset[str]]] = {}

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(**kwargs)
        fields = cls.model_fields
        cls._numeric_fields = frozenset(n for n, f in fields.items() if _numbers_only(f.annotation))
        plain = {}
        for name, info in fields.items():
            inner = _model_in(info.annotation)
            if isinstance(inner, type) and issubclass(inner, BaseModel):
                if not issubclass(inner, StrictModel):
                    numeric = inner.model_fields.items()
                    plain[name] = frozenset(n for n, f in numeric if _numbers_only(f.annotation))
        cls._plain_model_fields = plain

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_a_number(cls, value: Any, info: Any) -> Any:
        name = info.field_name
        if name in cls._numeric_fields and _holds_bool(value):
            raise PydanticCustomError(BOOL_NOT_NUMBER, "expected a number, not a boolean")
        if name in cls._plain_model_fields and isinstance(value, dict):
            for key in sorted(cls._plain_model_fields[name]):
                if _holds_bool(value.get(key)):
                    raise PydanticCustomError(
                        BOOL_NOT_NUMBER, "expected a number, not a boolean", {"key": key}
                    )
        return value


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


def format_validation_error(
    err: ValidationError, model: type[BaseModel], *, echo_max_chars: int | None = None
) -> list[str]:
    """Turn pydantic's errors into one readable line each; a value echoed is cut to
    ``echo_max_chars`` characters (default: ``configs/io_limits.yaml``'s)."""
    from ovtraj.config.io_limits import echoed

    def shown(value: Any) -> str:
        return echoed(repr(value), echo_max_chars)

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
            lines.append(f"{path} = {shown(value)}: out of range, allowed {allowed}")
            continue
        if kind == BOOL_NOT_NUMBER:
            key = (item.get("ctx") or {}).get("key")
            if key is not None:  # inside a plain pydantic model (the Earth model)
                path, value = f"{path}.{key}", value[key]
            lines.append(f"{path} = {shown(value)}: {item['msg']}")
            continue
        msg = item["msg"].removeprefix("Value error, ")
        if kind == "string_type" and isinstance(value, (datetime.date, datetime.datetime)):
            value = str(value)
            msg = "YAML read an unquoted date/time; quote it to give the text"
        suffix = f" (allowed {allowed})" if allowed else ""
        if not loc:
            lines.append(msg)
        elif value is None or isinstance(value, dict):
            lines.append(f"{path}: {msg}")
        else:
            lines.append(f"{path} = {shown(value)}: {msg}{suffix}")
    return lines


def model_from_dict(
    model: type[ModelT],
    data: Any,
    source: str = "",
    *,
    source_dir: Path | None = None,
    echo_max_chars: int | None = None,
) -> ModelT:
    """Validate a mapping into ``model``, raising :class:`ConfigError` (one line per field).

    ``source_dir`` is the folder relative paths in the data are relative to (the config
    file's); validators find it in the validation context. ``echo_max_chars``: see
    :func:`format_validation_error`.
    """
    if not isinstance(data, dict):
        raise ConfigError(
            [f"expected a mapping at the top level, got {type(data).__name__}"], source
        )
    try:
        return model.model_validate(data, context={"source_dir": source_dir})
    except ValidationError as err:
        raise ConfigError(
            format_validation_error(err, model, echo_max_chars=echo_max_chars), source
        ) from None


def _key_path(keys: list[Any]) -> str:
    return "".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in keys).lstrip(".")


def _unbuildable_value(text: str) -> str | None:
    """``key.path = value (line n): why`` of the first scalar YAML cannot build, if any.

    The document is composed into nodes (no values built), then every scalar is built
    alone, so the one that fails can be named.
    """
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError:
        return None
    builder = yaml.SafeLoader("")
    stack: list[tuple[Any, list[Any]]] = [(root, [])]
    while stack:
        node, keys = stack.pop()
        if isinstance(node, yaml.MappingNode):
            for key, value in reversed(node.value):
                stack.append((value, [*keys, key.value]))
        elif isinstance(node, yaml.SequenceNode):
            for index, item in reversed(list(enumerate(node.value))):
                stack.append((item, [*keys, index]))
        elif isinstance(node, yaml.ScalarNode):
            try:
                builder.construct_object(node, deep=True)
            except Exception as err:  # any constructor failure is the answer
                from ovtraj.config.io_limits import echoed

                kind = node.tag.rsplit(":", 1)[-1]
                where = _key_path(keys) or "<root>"
                return (
                    f"{where} = {echoed(node.value)} (line {node.start_mark.line + 1}): not a "
                    f"valid YAML {kind} ({echoed(str(err))}); quote it to give the text"
                )
    return None


def parse_yaml(text: str) -> Any:
    """The data of a YAML document; ``ValueError`` with one readable line for any failure.

    Syntax errors, and values the YAML constructors cannot build (an unquoted
    ``2026-13-45T00:00:00Z`` is read as a timestamp and fails with ``month must be in
    1..12``), are both reported, the latter with the key and the line.
    """
    try:
        return read_yaml(text)
    except yaml.YAMLError as err:
        raise ValueError(f"not valid YAML: {_yaml_problem(err)}") from None
    except Exception as err:  # the constructors raise ValueError, TypeError, OverflowError...
        where = _unbuildable_value(text)
        why = where or f"YAML cannot build a value: {type(err).__name__}: {err}"
        raise ValueError(why) from None


def _yaml_problem(err: yaml.YAMLError) -> str:
    """A YAML error as one line: ``line 2, column 2: while parsing a flow sequence; did
    not find expected ',' or ']'`` (PyYAML's own text spans four lines)."""
    mark = getattr(err, "problem_mark", None)
    what = [getattr(err, "context", None), getattr(err, "problem", None)]
    if mark is None or not any(what):
        return " ".join(str(err).split())
    return f"line {mark.line + 1}, column {mark.column + 1}: " + "; ".join(w for w in what if w)


def load_model(model: type[ModelT], path: str | Path) -> ModelT:
    """Read a YAML file and validate it into ``model``; every failure is a ConfigError.

    The file is read only if it is a regular file within ``config_file_max_kib``
    (``configs/io_limits.yaml``), and YAML anchors and aliases are refused
    (:func:`ovtraj.bounded_reads.read_yaml`).
    """
    path = Path(path)
    return model_from_dict(model, yaml_data(path), str(path), source_dir=path.resolve().parent)


def yaml_data(path: Path) -> Any:
    """The data of the YAML file ``path``, read and parsed as :func:`load_model` does
    (ConfigError naming the file)."""
    from ovtraj.config.io_limits import read_config_file

    text = read_config_file(path)
    try:
        return parse_yaml(text)
    except ValueError as err:
        raise ConfigError([str(err)], str(path)) from None
