"""The package's structure: downward imports, small rooms, no private names across modules.

These rules are the redesign's contract (README's Layout section): a module that breaks one
fails here with the offending import, module or function named.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "sigma_des"

_TOP = ("sigma_des.config", "sigma_des.api", "sigma_des.cli", "sigma_des.specs",
        "sigma_des.peer_specs", "sigma_des.factory", "sigma_des.live")
#: layer -> the packages/modules it must not import
FORBIDDEN: dict[str, tuple[str, ...]] = {
    "sigma_des.net": _TOP + ("sigma_des.events", "sigma_des.agents", "sigma_des.metrics"),
    "sigma_des.events": _TOP + ("sigma_des.agents",),
    "sigma_des.metrics": _TOP + ("sigma_des.events", "sigma_des.agents", "sigma_des.net.network"),
    "sigma_des.agents": _TOP + ("paho", "sigma_des.net", "sigma_des.events"),
}
#: the ground floor may import only itself and the error types
CORE_ALLOWED = ("sigma_des.core", "sigma_des.errors")

#: the top floors: commands, studies and the tools built on whole runs
_UPPER = ("sigma_des.cli", "sigma_des.sweep", "sigma_des.tuning", "sigma_lab.studies",
          "sigma_des.replay", "sigma_des.warmup", "sigma_des.plots")
#: the middle band, bottom to top: each must not import what sits above it
_MIDDLE = ("sigma_des.loading", "sigma_des.config", "sigma_des.factory", "sigma_des.cache",
           "sigma_des.record", "sigma_des.api", "sigma_des.live", "sigma_des.calibrate",
           "sigma_des.env")
#: what may sit above a middle module without being above it (``live`` draws plots)
_BESIDE = {"sigma_des.live": ("sigma_des.plots",)}
for _i, _mod in enumerate(_MIDDLE):
    FORBIDDEN[_mod] = tuple(m for m in _MIDDLE[_i + 1:] + _UPPER
                            if m not in _BESIDE.get(_mod, ()))
#: the package face (``sigma_des/__init__.py``): imported by users and the top floors only
FACE = "sigma_des"


def _within(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def module_name(path: Path) -> str:
    """Dotted module name of a file under the repository root."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports(mod: str, src: str, is_pkg: bool = False) -> list[tuple[int, str, list[str]]]:
    """``(line, imported module, imported names)`` of every import (relative ones resolved)."""
    pkg = mod.split(".") if is_pkg else mod.split(".")[:-1]
    out: list[tuple[int, str, list[str]]] = []
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name, []) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = pkg[: len(pkg) - node.level + 1] if node.level else []
            name = ".".join(base + ([node.module] if node.module else []))
            out.append((node.lineno, name, [a.name for a in node.names]))
    return out


def layering_violations(mod: str, src: str, is_pkg: bool = False) -> list[str]:
    """Imports of ``mod`` that point up or sideways, and private names taken from other modules."""
    bad = []
    below_face = not any(_within(mod, u) for u in _UPPER) and mod != FACE
    for line, imported, names in imports(mod, src, is_pkg):
        if below_face and imported == FACE:
            bad.append(f"{mod}:{line} imports the package face ({', '.join(names)})")
        if _within(mod, "sigma_des.core"):
            allowed = any(_within(imported, a) for a in CORE_ALLOWED)
            if _within(imported, "sigma_des") and not allowed:
                bad.append(f"{mod}:{line} imports {imported}")
        if _within(mod, "sigma_des") and _within(imported, "sigma_lab"):
            bad.append(f"{mod}:{line} imports the lab ({imported})")
        for layer, banned in FORBIDDEN.items():
            if _within(mod, layer) and any(_within(imported, b) for b in banned):
                bad.append(f"{mod}:{line} imports {imported}")
        if _within(imported, "sigma_des"):
            bad += [f"{mod}:{line} imports private {n} from {imported}"
                    for n in names if n.startswith("_") and not n.startswith("__")]
    return bad


def size_violations(src: str, max_lines: int = 500, max_function: int = 80) -> list[str]:
    """A module over ``max_lines`` lines, and every function over ``max_function`` lines."""
    bad = []
    if src.count("\n") > max_lines:
        bad.append(f"module has {src.count(chr(10))} lines")
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.end_lineno:
            n = node.end_lineno - node.lineno + 1
            if n > max_function:
                bad.append(f"function {node.name} (line {node.lineno}) has {n} lines")
    return bad


MODULES = sorted(PKG.rglob("*.py"))
SOURCES = (MODULES + sorted((ROOT / "experiments").rglob("*.py"))
           + sorted((ROOT / "lab").rglob("*.py")))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_downward(path: Path) -> None:
    bad = layering_violations(module_name(path), path.read_text(), path.name == "__init__.py")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_rooms_stay_small(path: Path) -> None:
    bad = size_violations(path.read_text())
    assert not bad, f"{path.relative_to(ROOT)}: " + "; ".join(bad)


def test_checker_finds_what_it_must() -> None:
    """Each rule fires on a hand-made offender and stays quiet on a clean module."""
    src = (
        "from sigma_des.config import Scenario\n"
        "from ..core.rng import _M1\n"
        "import paho.mqtt.client\n"
    )
    assert layering_violations("sigma_des.net.probe", src) == [
        "sigma_des.net.probe:1 imports sigma_des.config",
        "sigma_des.net.probe:2 imports private _M1 from sigma_des.core.rng",
    ]
    assert layering_violations("sigma_des.agents.probe", src)[-1] == (
        "sigma_des.agents.probe:3 imports paho.mqtt.client"
    )
    assert layering_violations("sigma_des.core.probe", "from sigma_des.net import kinds\n") == [
        "sigma_des.core.probe:1 imports sigma_des.net"
    ]
    assert layering_violations("sigma_des.config", src[:38]) == []
    # the middle band's upward imports removed by issue 23, one per rule
    assert layering_violations("sigma_des.api", "from sigma_des.sweep.local import run_all\n"
                               "from sigma_des import __version__\n") == [
        "sigma_des.api:1 imports sigma_des.sweep.local",
        "sigma_des.api:2 imports the package face (__version__)",
    ]
    assert layering_violations("sigma_des.config", "from sigma_des.tuning.fitted import f\n")
    assert layering_violations("sigma_des.factory", "from sigma_des.tuning.fitted import f\n")
    assert layering_violations("sigma_des.cache.warmup", "from sigma_des.api import compare\n")
    assert layering_violations("sigma_des.record.writer", "import sigma_des\n")
    assert layering_violations("sigma_des.config", "from sigma_des.api import compare\n")
    assert layering_violations("sigma_des.live.cli", "from sigma_des.plots import f\n") == []
    assert layering_violations("sigma_lab.studies.run", "import sigma_des\n") == []
    assert "sigma_des.net.spec:1 imports the lab (sigma_lab.reference)" in layering_violations(
        "sigma_des.net.spec", "from sigma_lab.reference import process_model\n")
    long_fn = "def f():\n" + "    x = 1\n" * 80
    assert size_violations(long_fn) == ["function f (line 1) has 81 lines"]
    assert size_violations(long_fn, max_lines=50)[0] == "module has 81 lines"
    assert size_violations("def f():\n" + "    x = 1\n" * 79) == []
