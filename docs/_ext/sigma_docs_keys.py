"""The scenario-key reference page, generated from the config dataclasses.

One table per scenario table (``[net.host_link.loss]`` …): dotted key, type, unit,
default (as ``sigma-des config`` prints it), allowed range (:mod:`sigma_des.ranges`,
probed against the validation by ``tests/docs/test_key_ranges.py``) and what the key does
(the class's ``Attributes:`` docstring).
"""

from __future__ import annotations

import re
from collections import OrderedDict

from sigma_des.ranges import Key, scenario_keys

__all__ = ["keys_page", "myst_inline"]

_INTRO = """\
# Scenario keys

Every key of a scenario, generated from the configuration classes. Set a key in a
scenario TOML file (`[net.host_link]` then `bandwidth_mbps = 100`) or on the command
line with `--set net.host_link.bandwidth_mbps=100`; `sigma-des config` prints the full
resolved scenario. A value outside its range is refused before anything runs: the
command exits with status 2 and one line naming the key and what it allows.

The *Range* column is the range the validation enforces (a test probes each one
against it). A bound written as another key (`[0, duration)`) is that key's value in
the same scenario. *Default* is what `sigma-des config` prints; an empty default
means the key is absent unless given (`latency_down`, the entries of `faults`).

"""


def myst_inline(text: str) -> str:
    """reST inline markup of a docstring as MyST: ````x```` → `` `x` ``, roles → ``{role}``."""
    text = re.sub(r":(\w+(?::\w+)?):`([^`]+)`", r"{\1}`\2`", text)
    text = re.sub(r"``([^`]+)``", r"`\1`", text)
    return text.replace("|", "\\|")


def _row(k: Key) -> str:
    default = f"`{k.default}`" if k.default else ""
    cells = [f"`{k.key}`", k.type, k.unit, default,
             myst_inline(k.range.describe(k.type == "int")), myst_inline(k.doc)]
    return "| " + " | ".join(cells) + " |"


def keys_page() -> str:
    """The page as MyST Markdown."""
    tables: OrderedDict[str, list[Key]] = OrderedDict({"": []})
    heads: dict[str, Key] = {}
    for k in scenario_keys():
        if k.type == "table":
            heads[k.key] = k
            tables.setdefault(k.key, [])
        else:
            tables.setdefault(k.section, []).append(k)
    out = [_INTRO]
    for name, keys in tables.items():
        if not keys:
            continue
        title = (f"`[[{name[:-2]}]]`" if name.endswith("[]") else f"`[{name}]`" if name
                 else "Top level")
        anchor = name.replace(".", "-").replace("[]", "") or "top-level"
        out.append(f"({'keys-' + anchor})=\n## {title}\n")
        if name in heads and heads[name].doc:
            out.append(myst_inline(heads[name].doc) + "\n")
        if name.endswith("[]"):
            out.append(f"A list, empty by default: each `[[{name[:-2]}]]` entry is one table "
                       "with the keys below (the defaults are those of a key left out).\n")
        out.append("| Key | Type | Unit | Default | Range | What it does |")
        out.append("| --- | --- | --- | --- | --- | --- |")
        out += [_row(k) for k in keys]
        out.append("")
    return "\n".join(out)
