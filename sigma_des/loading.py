"""Strict conversion of TOML tables into the frozen spec dataclasses, and back.

:func:`from_dict` builds any (nested) spec dataclass from a dict, naming the full
dotted key of an unknown key or a wrong type; :func:`plain` turns one back into
plain dicts and lists. :mod:`sigma_des.config` builds the scenario with them; the
tuning, sweep and live layers load their own tables the same way.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any

from sigma_des.errors import ConfigError
from sigma_des.net.latency import Dist

__all__ = ["from_dict", "plain"]


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", str(tp))


def _convert(value: Any, tp: Any, key: str) -> Any:
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        if tp is Dist and isinstance(value, int | float) and not isinstance(value, bool):
            value = {"dist": "constant", "value": float(value)}
        if not isinstance(value, dict):
            raise ConfigError(key, f"must be a table ({_type_name(tp)}), got {value!r}")
        return from_dict(typing.cast(type[Any], tp), value, key)
    if origin is tuple:
        (elem, _ellipsis) = typing.get_args(tp)
        if isinstance(value, str) and elem is str:
            value = [v.strip() for v in value.split(",") if v.strip()]
        if not isinstance(value, list | tuple):
            raise ConfigError(key, f"must be a list, got {value!r}")
        return tuple(_convert(v, elem, f"{key}[{i}]") for i, v in enumerate(value))
    if origin in (typing.Union, types.UnionType):
        # ``X | None``: an optional key (TOML has no null: present means X, absent None)
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) != 1 or len(typing.get_args(tp)) != 2:
            raise ConfigError(key, "internal: only `X | None` unions are supported")
        return _convert(value, args[0], key)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(key, f"must be true or false, got {value!r}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(key, f"must be an integer, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(key, f"must be a number, got {value!r}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(key, f"must be a string, got {value!r}")
        return value
    raise ConfigError(key, f"internal: unsupported type {tp!r}")


def from_dict(cls: type[Any], data: dict[str, Any], prefix: str = "") -> Any:
    """Build dataclass ``cls`` from nested dict ``data``, strictly.

    Raises:
        ConfigError: on an unknown key, a wrong type or an out-of-range value; the
            error's key is the full dotted path.
    """
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    kwargs: dict[str, Any] = {}
    for k, v in data.items():
        key = f"{prefix}.{k}" if prefix else k
        if k not in names:
            raise ConfigError(key, f"unknown key; allowed keys here: {', '.join(names)}")
        kwargs[k] = _convert(v, hints[k], key)
    try:
        return cls(**kwargs)
    except ConfigError as e:
        raise e.under(prefix) if prefix else e from None


def plain(v: Any) -> Any:
    """A dataclass (nested) as plain dicts and lists; an optional key left at None is
    omitted (TOML has no null, and a scenario without it hashes as before it existed)."""
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return {f.name: plain(x) for f in dataclasses.fields(v)
                if (x := getattr(v, f.name)) is not None}
    if isinstance(v, tuple | list):
        return [plain(x) for x in v]
    return v
