"""A scenario's text: ``key=value`` overrides, dotted keys, the scenario TOML file.

What :func:`sigma_des.config.load` reads before the values are checked: an override
``key=value`` (:func:`parse_set`; the value is TOML, else a string), a dotted key set in
the nested tables (:func:`set_key`) and a scenario file (:func:`read_toml`). Every
malformed input raises :class:`~sigma_des.errors.ConfigError` naming it.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from sigma_des.errors import ConfigError

__all__ = ["parse_set", "read_toml", "set_key", "split_item"]


def split_item(item: str, form: str, where: str) -> tuple[str, str]:
    """``(key, raw value)`` of ``item``, a ``key=...`` text.

    Args:
        item: the text.
        form: what it must look like (the error message when it has no ``=``).
        where: where it was given (``empty key in <where>``).

    Raises:
        ConfigError: no ``=``, or an empty key.
    """
    if "=" not in item:
        raise ConfigError(item, form)
    key, raw = item.split("=", 1)
    key = key.strip()
    if not key:
        raise ConfigError(item, f"empty key in {where}")
    return key, raw


def parse_set(item: str) -> tuple[str, Any]:
    """Parse one ``key=value`` override; the value is read as TOML, else as a string."""
    key, raw = split_item(item, "an override must look like key=value", "override")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key, value


def set_key(data: dict[str, Any], key: str, value: Any) -> None:
    """Set dotted ``key`` in the nested scenario table ``data`` (sub-tables made as needed).

    Raises:
        ConfigError: a prefix of ``key`` names a value that is not a table.
    """
    parts = key.split(".")
    cur = data
    for i, p in enumerate(parts[:-1]):
        nxt = cur.get(p)
        if nxt is None:
            nxt = cur[p] = {}
        if not isinstance(nxt, dict):
            raise ConfigError(".".join(parts[: i + 1]), "is not a table; cannot set a sub-key")
        cur = nxt
    cur[parts[-1]] = value


def read_toml(p: Path) -> dict[str, Any]:
    """The TOML table in scenario file ``p``; every file error is a ConfigError."""
    if p.is_dir():
        raise ConfigError(str(p), "is a directory, not a scenario file (a TOML file)")
    try:
        return tomllib.loads(p.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        from sigma_des.shipped import names

        raise ConfigError(str(p), "scenario file not found (shipped scenarios, runnable by "
                                  f"name: {', '.join(names())})") from None
    except UnicodeDecodeError as e:
        raise ConfigError(
            str(p), f"not a text (UTF-8 TOML) file: undecodable byte at offset {e.start}"
        ) from None
    except OSError as e:
        raise ConfigError(str(p), f"cannot read scenario file: {e.strerror or e}") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(str(p), f"not valid TOML: {e}") from None
