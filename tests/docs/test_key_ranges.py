"""The key reference's ranges (sigma_des.ranges) agree with the validation, and cover
every key ``sigma-des config`` prints.

Each range is probed against the spec classes' own checks: a value on a closed end is
accepted, the end of an open one and a value just outside are refused with a
``ConfigError``; every choice is accepted and a value that is none of them refused.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from sigma_des.config import load
from sigma_des.errors import ConfigError
from sigma_des.ranges import Key, Range, scenario_keys

ROOT = Path(__file__).resolve().parents[2]

#: What a key's probe needs set besides it (the other keys its check depends on).
_DEP = {"deployment.preset": "colocated"}
_DEMAND = {**_DEP, "deployment.host_demand": 0.5, "deployment.server_demand": 0.5}
_WAKE = {**_DEMAND, "deployment.host_wake": 0.5, "deployment.server_wake": 0.5}
#: A delay sample file (shipped with the tests): the ``empirical`` distribution needs one.
SAMPLES = Path(__file__).resolve().parent / "data" / "delays.txt"
CONTEXT: dict[str, dict[str, Any]] = {
    "f_trig": {"bides.f_trig_min": 1e-9},
    "net.middleware": {"net.transport": "datagram", "net.qos": 0},
    "bides.lag_high": {"bides.lag_low": 0},
    "net.host_link.latency.dist": {"net.host_link.latency.file": str(SAMPLES)},
    "net.host_link.latency.high": {"net.host_link.latency.low": 0.001},
    **{f"deployment.{k}": _DEP for k in ("cores", "background", "host_demand",
                                         "server_demand", "server_tick", "lock_switch",
                                         "host_runq", "server_runq", "broker_runq",
                                         "runq_growth", "broker_runq_growth",
                                         "server_runq_growth")},
    **{f"deployment.{w}_{k}": _DEMAND for w in ("host", "server")
       for k in ("wake", "record", "net_msg", "net_wake")},
    **{f"deployment.{w}_wake_side": _WAKE for w in ("host", "server")},
    "deployment.bundle": {"deployment.clients": "host"},
}
#: A fault every fault probe starts from (a slow node), and what some fields need.
FAULT = {"kind": "slow", "node": 0, "host": 0, "frame": 0, "start": 0.0, "factor": 2.0}
FAULT_CONTEXT = {"host": {"kind": "degrade"}, "frame": {"kind": "drop"}}


def _probed() -> list[Key]:
    """The first key of every (class, field) whose range is probed."""
    seen: set[tuple[type, str]] = set()
    out = []
    for k in scenario_keys():
        if k.type == "table" or not k.range.probe or (k.cls, k.name) in seen:
            continue
        seen.add((k.cls, k.name))
        out.append(k)
    return out


def _accepts(key: Key, value: Any) -> bool:
    """True if the scenario loads with ``key`` set to ``value`` (on top of its context)."""
    try:
        if key.key.startswith("faults[]."):
            fault = {**FAULT, **FAULT_CONTEXT.get(key.name, {}), key.name: value}
            load(None, faults=[fault])
        else:
            load(None, **{**CONTEXT.get(key.key, {}), key.key: value})
    except ConfigError:
        return False
    return True


def _bound(key: Key, b: float | str) -> float:
    """A bound's value: a number, a sibling key (``low``) or a key of the scenario."""
    if not isinstance(b, str):
        return b
    fault = {**FAULT, **FAULT_CONTEXT.get(key.name, {})}
    if key.key.startswith("faults[].") and b in fault:
        return float(fault[b])
    ctx = CONTEXT.get(key.key, {})
    sibling = key.key.rsplit(".", 1)[0] + "." + b
    if sibling in ctx:
        return float(ctx[sibling])
    obj: Any = load(None, **ctx)
    path = b if "." in b or hasattr(obj, b) else sibling
    for part in path.split("."):
        obj = getattr(obj, part)
    return float(obj)


def _cases(key: Key) -> list[tuple[Any, bool]]:
    """``(value, accepted?)`` pairs probing ``key``'s range."""
    r: Range = key.range
    if r.choices:
        cases = [(c, True) for c in r.choices]
        if key.type == "str":
            cases.append(("no-such-choice", False))
        elif key.type == "int":
            cases += [(min(r.choices) - 1, False), (max(r.choices) + 1, False)]
        return cases
    integer = key.type == "int"
    cases = [(a, True) for a in r.also]
    for end, is_lo in ((r.lo, True), (r.hi, False)):
        if end is None:
            if not is_lo and not integer:
                cases.append((math.inf, False))  # an unbounded float key is still finite
            continue
        v = _bound(key, end)
        if math.isinf(v):
            cases.append((v, not (r.hi_open if not is_lo else r.lo_open)))
            continue
        eps = 1 if integer else max(abs(v), 1.0) * 1e-9
        step = -eps if is_lo else eps
        is_open = r.lo_open if is_lo else r.hi_open
        v = int(v) if integer else v
        cases.append((v, not is_open))
        out = v + step if not is_open else v
        while out in r.also:
            out += step
        cases.append((out, False))
        if is_open:
            cases.append((v - step, True))
    return cases


@pytest.mark.parametrize("key", _probed(), ids=lambda k: k.key)
def test_range_agrees_with_validation(key: Key) -> None:
    wrong = [(v, ok) for v, ok in _cases(key) if _accepts(key, v) != ok]
    assert not wrong, (
        f"{key.key}: documented as {key.range.describe(key.type == 'int')}, but the "
        f"validation {'; '.join(('refuses ' if ok else 'accepts ') + repr(v) for v, ok in wrong)}"
    )


def test_probe_catches_a_wrong_range() -> None:
    """The probe is not vacuous: a range one step off is reported."""
    key = next(k for k in scenario_keys() if k.key == "history_frames")
    off = Key(key.key, key.section, key.type, key.unit, key.default, Range(17, 100_000),
              key.doc, key.cls, key.name)
    assert (16, False) in _cases(off) and _accepts(off, 16)  # documented 17, accepts 16
    assert not _accepts(off, 15)


def _printed_keys() -> list[str]:
    """Every leaf key of ``sigma-des config``'s TOML (list entries as ``name[].key``)."""
    import tomllib

    out = subprocess.run([sys.executable, "-m", "sigma_des.cli", "config"], check=True,
                         capture_output=True, text=True, cwd=ROOT).stdout
    keys: list[str] = []

    def walk(d: dict[str, Any], prefix: str) -> None:
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v, f"{prefix}{k}.")
            elif isinstance(v, list) and v and isinstance(v[0], dict):
                walk(v[0], f"{prefix}{k}[].")
            elif v == [] and k == "faults":  # a list of tables, empty by default
                keys.append(f"{prefix}{k}[]")
            else:
                keys.append(prefix + k)

    walk(tomllib.loads(out), "")
    return keys


def test_every_printed_key_has_a_range() -> None:
    printed = _printed_keys()
    documented = {k.key: k for k in scenario_keys()}
    assert len(printed) > 150
    missing = [k for k in printed if k not in documented]
    assert not missing, f"keys of `sigma-des config` missing from sigma_des.ranges: {missing}"
    for k in printed:
        text = documented[k].range.describe(documented[k].type == "int")
        assert text and (text == "any" or re.search(r"[\d\[(≥≤<>]|one of|a |\"", text)), k


def test_generated_reference_lists_every_key(tmp_path: Path) -> None:
    """The page the docs build writes has a row per printed key, with its range."""
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        from sigma_docs_keys import keys_page
    finally:
        sys.path.pop(0)
    page = keys_page()
    for k in _printed_keys():
        if k.endswith("[]"):  # a list of tables: its heading, then its keys' rows
            assert f"## `[[{k[:-2]}]]`" in page, k
            continue
        row = next((ln for ln in page.splitlines() if ln.startswith(f"| `{k}` |")), None)
        assert row is not None, f"{k} has no row in the scenario-key reference"
        cells = [c.strip() for c in row.strip("|").split(" | ")]
        assert len(cells) == 6 and cells[4], f"{k}: no range in its row {row!r}"


def test_ranges_in_words_agree_too() -> None:
    """The keys whose range is words, not bounds: each choice named is accepted."""
    from sigma_des.config import ALL_METHODS, DYNAMICS_BUILTIN
    from sigma_des.factory import make_behaviour

    keys = {k.key: k for k in scenario_keys()}
    assert [k.key for k in keys.values() if k.type != "table" and not k.range.probe
            and k.name not in ("file", "dynamics_params")] == [
        "dynamics", "methods", "commands.behaviour"]
    for d in DYNAMICS_BUILTIN + ("jsbsim:c172x",):
        assert f'"{d.split(":")[0]}' in keys["dynamics"].range.describe()
        load(None, dynamics=d)
    with pytest.raises(ConfigError):
        load(None, dynamics="glider")
    for m in ALL_METHODS:
        assert f'"{m}"' in keys["methods"].range.describe()
        load(None, methods=[m])
    for bad in ([], ["none", "none"], ["warp"]):
        with pytest.raises(ConfigError):
            load(None, methods=bad)
    for b in keys["commands.behaviour"].range.choices:
        make_behaviour(load(None, **{"commands.behaviour": b}))
    with pytest.raises(ConfigError):
        make_behaviour(load(None, **{"commands.behaviour": "swarm-dance"}))
