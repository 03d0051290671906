"""Typed configuration: one schema per YAML file, defaults in one place, unknown keys rejected.

Schemas are pydantic models with ``extra="forbid"``. :func:`load_yaml_model` reads a YAML file
into a schema and turns validation failures into :class:`~gaitcap.errors.ConfigError` messages
that name the file and the dotted key, and suggest the closest valid key for a typo.
"""

from __future__ import annotations

import difflib
import logging
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError, ValidationInfo, field_validator

from gaitcap.errors import ConfigError

M = TypeVar("M", bound=BaseModel)

log = logging.getLogger("gaitcap.config")
#: the files whose left-out keys were warned about (:func:`load_config_file`)
_WARNED: set[tuple[str, tuple[str, ...]]] = set()

CONFIG_DIR = Path(__file__).resolve().parent / "configs"

#: libyaml's safe loader when PyYAML was built with it (its wheels are): the same documents as the
#: pure-Python SafeLoader, 15 times faster (about 0.1 s of a run's start-up for the shipped files)
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _UniqueKeys(_LOADER):  # type: ignore[misc, valid-type]
    """The safe loader, refusing a mapping that gives a key twice (PyYAML keeps the last silently:
    a key added to a file that already had it further down would be ignored)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, yaml.Node] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=deep)
            try:
                first = seen.setdefault(key, key_node)
            except TypeError:  # an unhashable key: the base class says so
                continue
            if first is not key_node:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} given twice (first on line {first.start_mark.line + 1})",
                    key_node.start_mark)  # fmt: skip
        return super().construct_mapping(node, deep=deep)


def parse_yaml(text: str) -> Any:
    """``yaml.safe_load`` of ``text``, through libyaml when available, refusing a key given twice in
    one mapping (raises ``yaml.YAMLError``)."""
    return yaml.load(text, Loader=_UniqueKeys)


class Strict(BaseModel):
    """Base of every config schema: unknown keys are errors, values are validated on assignment, and a
    number must be finite (YAML's .inf and .nan pass every bound check otherwise).

    A value the schema refuses on assignment (``cfg.smoothing.cutoff_hz = -1``, or a key it does not
    have) raises :class:`ConfigError` naming the schema and the key, as a file's value does; the
    pydantic error is its ``__cause__``.
    """

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=False, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_boolean_for_a_number(cls, value: Any, info: ValidationInfo) -> Any:
        """A YAML boolean (``true``, ``no``, ``on``...) where a number is expected is refused: pydantic
        reads it as 1 or 0 (``height_m: true`` was a 1.0 m subject)."""
        field = cls.model_fields.get(info.field_name or "")
        if field is not None and _boolean_for_a_number(value, field.annotation):
            raise ValueError("a number is expected, not a boolean (YAML reads true/false, yes/no, on/off as booleans)")
        return value

    def __setattr__(self, name: str, value: Any) -> None:
        try:
            super().__setattr__(name, value)
        except ValidationError as e:
            raise ConfigError(format_validation_error(e, type(self).__name__, type(self))) from e


def _number_types(annotation: Any) -> tuple[bool, bool]:
    """Whether ``annotation`` (a field's type) admits a number (int, float), and a boolean."""
    if annotation is bool:
        return False, True
    if annotation in (int, float):
        return True, False
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _number_types(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        found = [_number_types(a) for a in typing.get_args(annotation)]
        return any(n for n, _ in found), any(b for _, b in found)
    return False, False


def _boolean_for_a_number(value: Any, annotation: Any) -> bool:
    """``value`` is a boolean where ``annotation`` expects a number, itself or as an item of a list,
    tuple or mapping of numbers."""
    if isinstance(value, bool):
        number, boolean = _number_types(annotation)
        return number and not boolean
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        containers = [a for a in args if typing.get_origin(a) in (list, tuple, set, frozenset, dict)]
        return bool(containers) and all(_boolean_for_a_number(value, a) for a in containers)
    if origin in (list, tuple, set, frozenset) and isinstance(value, (list, tuple)):
        items = [a for a in args if a is not Ellipsis]
        if not items:
            return False
        return any(_boolean_for_a_number(v, items[min(k, len(items) - 1)]) for k, v in enumerate(value))
    if origin is dict and isinstance(value, Mapping) and len(args) == 2:
        return any(_boolean_for_a_number(v, args[1]) for v in value.values())
    return False


def read_yaml(path: str | Path) -> Any:
    """Read a YAML file, raising :class:`ConfigError` naming the file on any failure."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as e:
        raise ConfigError(f"{path}: file not found") from e
    except OSError as e:
        raise ConfigError(f"{path}: cannot read ({e.strerror})") from e
    except UnicodeDecodeError as e:
        line = e.object[: e.start].count(b"\n") + 1
        raise ConfigError(f"{path}: line {line}: not UTF-8 text (byte 0x{e.object[e.start]:02x}); save the file as "
                          f"UTF-8") from e
    try:
        return parse_yaml(text)
    except yaml.YAMLError as e:
        raise ConfigError(f"{path}: not valid YAML: {yaml_problem(e)}") from e


def yaml_problem(err: yaml.YAMLError) -> str:
    """A parser's error on one line, with its line and column in the file (PyYAML's own text spans
    three to four lines and names the text as ``"<unicode string>"``, not the file)."""
    if not isinstance(err, yaml.MarkedYAMLError) or err.problem_mark is None:
        return " ".join(str(err).split())
    mark = err.problem_mark
    text = f"{err.problem} at line {mark.line + 1}, column {mark.column + 1}"
    if err.context and err.context_mark is not None:
        text += f" ({err.context} at line {err.context_mark.line + 1})"
    return text


def _allowed_keys(model: type[BaseModel], loc: tuple[Any, ...]) -> list[str]:
    """Field names of the sub-model that ``loc`` points into (for "did you mean" suggestions).

    Parts of ``loc`` that are list indices or free dictionary keys (``segments.thigh_l``) do not
    change the model; parts that are field names descend into that field's model.
    """
    current: Any = model
    for part in loc[:-1]:
        fields = getattr(current, "model_fields", None) or {}
        if isinstance(part, str) and part in fields:
            current = _inner_model_of_annotation(fields[part].annotation)
    fields = getattr(current, "model_fields", None)
    return list(fields) if fields else []


def _inner_model_of_annotation(annotation: Any) -> Any:
    """Find a BaseModel class inside an annotation such as ``dict[str, X]`` or ``list[X] | None``."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in getattr(annotation, "__args__", ()) or ():
        found = _inner_model_of_annotation(arg)
        if found is not None:
            return found
    return None


def format_validation_error(err: ValidationError, source: str, model: type[BaseModel]) -> str:
    """Render a pydantic error as ``source: key.path: message`` lines with suggestions."""
    lines = []
    for item in err.errors():
        loc = tuple(item.get("loc", ()))
        key = ".".join(str(p) for p in loc) or "(top level)"
        msg = item.get("msg", "invalid value")
        if item.get("type") in ("extra_forbidden", "no_such_attribute") and loc:
            allowed = _allowed_keys(model, loc)
            close = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
            msg = "unknown key" + (f" (did you mean '{close[0]}'?)" if close else "")
            if allowed and not close:
                msg += f"; valid keys: {', '.join(sorted(allowed))}"
        lines.append(f"{source}: {key}: {msg}")
    return "\n".join(lines)


def model_from_mapping(model: type[M], data: Any, source: str, if_missing: str = "") -> M:
    """Validate ``data`` (a mapping) against ``model``; errors name ``source`` and the key, and a
    required key missing adds the line ``source: if_missing`` (when given)."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: expected a mapping of keys at the top level, got {type(data).__name__}")
    try:
        return model.model_validate(dict(data))
    except ValidationError as e:
        text = format_validation_error(e, source, model)
        if if_missing and any(item.get("type") == "missing" for item in e.errors()):
            text += f"\n{source}: {if_missing}"
        raise ConfigError(text) from e


def load_yaml_model(model: type[M], path: str | Path) -> M:
    """Read ``path`` and validate it against ``model``."""
    return model_from_mapping(model, read_yaml(path), str(path))


def load_config_file(model: type[M], path: str | Path | None, shipped: str) -> M:
    """The configuration ``path`` (None: the shipped ``configs/<shipped>``). A file given in place of
    the shipped one is read whole: one that lacks required keys is told to start from a copy of the
    shipped one, and one that leaves out keys whose schema default is not the shipped value is warned
    about, naming them (:func:`defaults_unlike_shipped`)."""
    shipped_path = default_config_path(shipped)
    if path is None:
        return load_yaml_model(model, shipped_path)
    data = read_yaml(path)
    cfg = model_from_mapping(model, data, str(path),
                             f"a configuration file replaces the shipped one whole (a file of a few keys is not "
                             f"merged into it): start from a copy of {shipped_path}")  # fmt: skip
    differ = defaults_unlike_shipped(model, data, read_yaml(shipped_path))
    said = (str(Path(path).resolve()), tuple(differ))
    if differ and said not in _WARNED:  # once a process: a batch reads the file for every session
        _WARNED.add(said)
        log.warning("%s leaves out %s, which the shipped %s sets otherwise, so the schema's defaults are taken "
                    "(%s): copy the keys from %s to track as shipped", path, ", ".join(differ), shipped_path.name,
                    "; ".join(f"{k}: {v}" for k, v in differ.items()), shipped_path)  # fmt: skip
    return cfg


def defaults_unlike_shipped(model: type[BaseModel], data: Any, shipped: Any, prefix: str = "") -> dict[str, str]:
    """The keys (dotted) the shipped file sets that ``data`` leaves out and whose schema default is not
    the shipped value, each with ``"default X, shipped Y"``. Sections that are schemas of their own are
    compared key by key; any other value (a list, a mapping of free keys) as a whole."""
    data = data if isinstance(data, Mapping) else {}
    shipped = shipped if isinstance(shipped, Mapping) else {}
    out: dict[str, str] = {}
    for name, field in model.model_fields.items():
        if name not in shipped:
            continue
        sub = field.annotation
        if isinstance(sub, type) and issubclass(sub, BaseModel):  # a section left out is compared as an empty one
            out.update(defaults_unlike_shipped(sub, data.get(name), shipped[name], f"{prefix}{name}."))
            continue
        if name in data or field.is_required():
            continue
        default = field.get_default(call_default_factory=True)
        if _plain(default) != _plain(shipped[name]):
            out[f"{prefix}{name}"] = f"default {_short(default)}, shipped {_short(shipped[name])}"
    return out


def _plain(value: Any) -> Any:
    """``value`` with tuples as lists and models as mappings, to compare a default with YAML."""
    if isinstance(value, BaseModel):
        return _plain(value.model_dump())
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _short(value: Any, width: int = 40) -> str:
    text = repr(_plain(value))
    return text if len(text) <= width else text[: width - 3] + "..."


def default_config_path(name: str) -> Path:
    """Path of a configuration file shipped with gaitcap (``configs/<name>``)."""
    path = CONFIG_DIR / name
    if not path.exists():
        raise ConfigError(f"{path}: default configuration not found (broken installation?)")
    return path
