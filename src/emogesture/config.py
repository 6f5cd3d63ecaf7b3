"""Dataclass configs: from YAML/dicts, with ``a.b=value`` overrides; unknown keys are errors.

Values given as strings (on the command line) are parsed by the field's declared type, so a
boolean accepts only true/false/yes/no/1/0 (never ``bool("False") == True``).
"""

from __future__ import annotations

import dataclasses
import types
import typing
from os import PathLike
from pathlib import Path
from typing import Any, TypeVar

import yaml

from emogesture.errors import ConfigError, InputFileError

T = TypeVar("T")

_TRUE = {"true", "yes", "on", "1"}
_FALSE = {"false", "no", "off", "0"}


def parse_bool(text: str | bool) -> bool:
    """Parse a boolean strictly: true/false, yes/no, on/off, 1/0 (any case)."""
    if isinstance(text, bool):
        return text
    t = str(text).strip().lower()
    if t in _TRUE:
        return True
    if t in _FALSE:
        return False
    raise ConfigError(f"not a boolean: {text!r} (use true or false)")


def _coerce(value: Any, tp: Any, where: str) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        if value is None or (isinstance(value, str) and value.lower() in ("none", "null")):
            if type(None) in args:
                return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _coerce(value, a, where)
            except ConfigError as e:
                errors.append(str(e))
        raise ConfigError(f"{where}: {value!r} fits none of {tp}")
    if dataclasses.is_dataclass(tp):
        if isinstance(value, tp):
            return value
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a mapping, got {value!r}")
        return from_dict(tp, value, where)
    if tp is bool:
        return parse_bool(value)
    if tp in (int, float, str):
        try:
            if tp is int and isinstance(value, float) and not value.is_integer():
                raise ValueError
            return tp(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{where}: {value!r} is not a valid {tp.__name__}")
    if origin in (tuple, list):
        if isinstance(value, str):
            value = yaml.safe_load(value) if value.strip().startswith("[") else [v for v in value.split(",") if v]
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {value!r}")
        item = args[0] if args else Any
        seq = [_coerce(v, item, f"{where}[{i}]") for i, v in enumerate(value)]
        return tuple(seq) if origin is tuple else seq
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a mapping, got {value!r}")
        return dict(value)
    return value


#: A retired option's value that does anything (:func:`from_dict`): any value is inert.
ANY_VALUE = object()


def from_dict(cls: type[T], data: dict, where: str = "config") -> T:
    """Build dataclass ``cls`` from a (nested) dict; unknown keys raise ConfigError.

    A class may name options it no longer has, tried and not adopted, with the value that left them off
    (``RETIRED: ClassVar[dict]``, :data:`ANY_VALUE` for one that did nothing while another was off): a stored
    config holding one at that value reads as if it were not there (files saved before it was removed); at
    any other value it is a one-line error, since this version cannot do what it asked."""
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls) if f.init}
    retired = getattr(cls, "RETIRED", {})
    for key in [k for k in data if k in retired and k not in names]:
        off = retired[key]
        if off is not ANY_VALUE and data[key] != off:
            raise ConfigError(f"{where}.{key} = {data[key]!r}: this option was removed (tried and not adopted); "
                              "a model or run that used it cannot be read by this version")
        data = {k: v for k, v in data.items() if k != key}
    unknown = set(data) - names
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)}; known: {sorted(names)}")
    kwargs = {k: _coerce(v, hints[k], f"{where}.{k}") for k, v in data.items()}
    return cls(**kwargs)


def to_dict(obj: Any) -> dict:
    """A dataclass as plain, YAML/JSON-safe data (tuples become lists)."""

    def plain(v: Any) -> Any:
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        return v

    return plain(dataclasses.asdict(obj))


def changed_keys(old: dict, new: dict) -> list[str]:
    """The top-level keys whose values differ between two settings dicts (one missing counts), sorted."""
    return sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))


def apply_overrides(cls: type[T], base: dict, overrides: list[str]) -> T:
    """Apply ``a.b=value`` strings to a dict of ``cls`` and build it."""
    data = _deepcopy(base)
    for item in overrides:
        if "=" not in item:
            raise ConfigError(f"override {item!r} is not of the form key=value")
        key, value = item.split("=", 1)
        node: dict = data
        parts = key.strip().split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise ConfigError(f"override {item!r}: {p} is not a section")
        node[parts[-1]] = value
    return from_dict(cls, data)


def load_config(cls: type[T], path: str | PathLike[str] | None = None, overrides: list[str] | None = None,
                base: dict | None = None) -> T:
    """``cls`` from defaults (or ``base``), then a YAML file, then ``a.b=value`` overrides."""
    data = _deepcopy(base) if base is not None else to_dict(cls())
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise InputFileError(p, "config file not found")
        try:
            loaded = yaml.safe_load(p.read_text()) or {}
        except yaml.YAMLError as e:
            raise InputFileError(p, f"not valid YAML ({str(e).splitlines()[0]})")
        if not isinstance(loaded, dict):
            raise InputFileError(p, "a config file must hold a mapping")
        _merge(data, loaded)
    return apply_overrides(cls, data, overrides or [])


def _merge(dst: dict, src: dict) -> None:
    for k, v in src.items():
        if isinstance(v, dict) and isinstance(dst.get(k), dict):
            _merge(dst[k], v)
        else:
            dst[k] = v


def _deepcopy(d: dict) -> dict:
    return {k: _deepcopy(v) if isinstance(v, dict) else v for k, v in d.items()}
