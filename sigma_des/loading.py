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
from sigma_des.net.latency import DIST_NAMES, Dist

__all__ = ["from_dict", "plain"]


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", str(tp))


def _over_default(value: dict[str, Any], default: Any, key: str) -> dict[str, Any]:
    """A distribution table completed from the key's own default.

    A table without ``dist``, or naming the default's ``dist``, changes only the fields
    it gives: the others keep the key's default (``--set compute.step_time.mean=0.05``
    keeps the default's lognormal and its ``std``). A table naming another ``dist`` is
    a new distribution: the fields it omits are 0 (the bare :class:`Dist`).
    """
    if not isinstance(default, Dist):
        if "dist" not in value:
            raise ConfigError(f"{key}.dist", "required: this key has no default distribution "
                              f"to complete; allowed: {', '.join(DIST_NAMES)}")
        return value
    if "dist" in value and value["dist"] != default.dist:
        return value
    return {**plain(default), **value}


def _convert(value: Any, tp: Any, key: str, default: Any = None) -> Any:
    origin = typing.get_origin(tp)
    if dataclasses.is_dataclass(tp):
        if tp is Dist and isinstance(value, int | float) and not isinstance(value, bool):
            value = {"dist": "constant", "value": float(value)}
        if not isinstance(value, dict):
            raise ConfigError(key, f"must be a table ({_type_name(tp)}), got {value!r}")
        if tp is Dist:
            value = _over_default(value, default, key)
        return from_dict(typing.cast(type[Any], tp), value, key, default)
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
        return _convert(value, args[0], key, default)
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


def _field_default(f: dataclasses.Field[Any], default: Any) -> Any:
    """Field ``f``'s default: the parent default's value, else the field's own."""
    if default is not None:
        return getattr(default, f.name, None)
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None


def from_dict(cls: type[Any], data: dict[str, Any], prefix: str = "",
              default: Any = None) -> Any:
    """Build dataclass ``cls`` from nested dict ``data``, strictly.

    A distribution table (a :class:`Dist`) is read over the key's own default (see
    :func:`_over_default`): the default of its field, or ``default``'s value of it.

    Raises:
        ConfigError: on an unknown key, a wrong type or an out-of-range value; the
            error's key is the full dotted path.
    """
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs: dict[str, Any] = {}
    for k, v in data.items():
        key = f"{prefix}.{k}" if prefix else k
        if k not in fields:
            raise ConfigError(key, f"unknown key; allowed keys here: {', '.join(fields)}")
        sub = _field_default(fields[k], default) if isinstance(v, dict) else None
        kwargs[k] = _convert(v, hints[k], key, sub)
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
