"""Which Dask worker each live physics host runs on: ``--placement spread|pack|FILE``.

* ``spread``: host ``h`` on worker ``h mod W`` (workers sorted by name, then address):
  one host per machine when there are as many workers as hosts, the ``dedicated``
  deployment preset.
* ``pack``: every host on the first worker, the ``colocated`` preset (one machine).
* ``FILE``: a TOML map, hosts not listed spread (or packed, ``default = "pack"``) over
  the workers::

      default = "spread"          # or "pack": hosts not listed below
      [hosts]
      0 = "rack-a"                # a worker name (dask worker --name) or address
      1 = "tcp://10.0.0.7:40100"
      2 = { resources = { gpu = 1 } }   # any worker started with --resources "gpu=1"

A :class:`Pin` is what Dask is asked for: ``workers=[...]`` (no other worker allowed)
or ``resources={...}``. Every name, address and resource is checked against the
cluster's workers before anything starts; a wrong one is an error naming the host.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sigma_des.errors import ConfigError

__all__ = ["Pin", "Worker", "assign", "read_placement"]

KEY = "--placement"


@dataclass(frozen=True)
class Worker:
    """A Dask worker as the scheduler lists it."""

    address: str
    name: str
    resources: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class Pin:
    """Where one host may run: on ``worker`` (an address) or any worker with ``resources``."""

    worker: str | None = None
    resources: dict[str, float] | None = None


def read_placement(text: str) -> str | dict[str, Any]:
    """``spread``, ``pack`` or the parsed TOML of a placement file.

    Raises:
        ConfigError: naming ``--placement``: neither keyword nor a readable TOML file, or
            a key other than ``default`` and ``hosts``.
    """
    if text in ("spread", "pack"):
        return text
    p = Path(text)
    if not p.is_file():
        raise ConfigError(KEY, f"must be spread, pack or a TOML file, got {text!r}")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise ConfigError(KEY, f"{text}: not readable as TOML ({e})") from None
    extra = set(data) - {"default", "hosts"}
    if extra:
        raise ConfigError(KEY, f"{text}: unknown key {sorted(extra)[0]!r}; allowed: default, "
                          "hosts")
    if data.get("default", "spread") not in ("spread", "pack"):
        raise ConfigError(KEY, f"{text}: default must be 'spread' or 'pack', got "
                          f"{data['default']!r}")
    if not isinstance(data.get("hosts", {}), dict):
        raise ConfigError(KEY, f"{text}: [hosts] must be a table of host = worker")
    return data


def _by_name(workers: list[Worker], what: str, h: int, src: str) -> str:
    for w in workers:
        if what in (w.name, w.address):
            return w.address
    names = ", ".join(w.name for w in workers)
    raise ConfigError(KEY, f"{src}: host {h}: no worker named or at {what!r}; the "
                      f"scheduler has {names}")


def _pin(v: Any, h: int, workers: list[Worker], src: str) -> Pin:
    if isinstance(v, str):
        return Pin(worker=_by_name(workers, v, h, src))
    if isinstance(v, dict) and set(v) == {"worker"} and isinstance(v["worker"], str):
        return Pin(worker=_by_name(workers, v["worker"], h, src))
    if isinstance(v, dict) and set(v) == {"resources"} and isinstance(v["resources"], dict):
        res = v["resources"]
        if not res or not all(isinstance(x, (int, float)) and x > 0 for x in res.values()):
            raise ConfigError(KEY, f"{src}: host {h}: resources must be positive numbers")
        if not any(all(w.resources.get(k, 0) >= x for k, x in res.items()) for w in workers):
            raise ConfigError(KEY, f"{src}: host {h}: no worker has resources {res}")
        return Pin(resources={k: float(x) for k, x in res.items()})
    raise ConfigError(KEY, f"{src}: host {h}: must be a worker name, {{worker = ...}} or "
                      f"{{resources = {{...}}}}, got {v!r}")


def assign(hosts: int, workers: list[Worker], placement: str | dict[str, Any],
           src: str = KEY) -> list[Pin]:
    """Each host's :class:`Pin` on ``workers`` (sorted here by name, then address).

    Raises:
        ConfigError: no workers; a host key that is not an index below ``hosts``; a
            worker name, address or resource the cluster does not have.
    """
    if not workers:
        raise ConfigError("--scheduler", "the scheduler has no workers; start `dask worker "
                          "tcp://SCHEDULER:PORT` on each machine first")
    ws = sorted(workers, key=lambda w: (str(w.name), w.address))
    table = {} if isinstance(placement, str) else placement.get("hosts", {})
    mode = placement if isinstance(placement, str) else placement.get("default", "spread")
    pins: list[Pin] = []
    for key in table:
        if not key.isdigit() or int(key) >= hosts:
            raise ConfigError(KEY, f"{src}: host {key!r} is not a host index in 0..{hosts - 1}")
    for h in range(hosts):
        if str(h) in table:
            pins.append(_pin(table[str(h)], h, ws, src))
        else:
            pins.append(Pin(worker=ws[h % len(ws)].address if mode == "spread"
                            else ws[0].address))
    return pins
