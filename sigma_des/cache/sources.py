"""The source files numba's compiled kernels depend on, and their fingerprint.

numba's ``cache=True`` invalidates a cached kernel only when the file *defining* it
changes; the constants it froze (``events/fast/codes.py``, ``layout.py``) and the jitted callees it
inlined from other modules are not checked, so an edit there would load stale code.
:func:`fingerprint` hashes every file whose content can change compiled code, and
:mod:`sigma_des.jitcache` names numba's cache directory after it, so such an edit
gives a fresh directory instead of stale kernels.

The covered set (:func:`kernel_sources`) is narrow on purpose: a whole-package hash
would make every edit of a CLI or plotting module recompile ~45 CPU-s of kernels. It
is found by a text scan (cheap enough for every import, unlike parsing every module):

* the *roots*: modules that import numba at module level or start a line with a
  numba-style decorator (``njit``, ``jit``, ``intrinsic``, ... after an ``@``) — this
  catches the fast core's modules that take ``jit`` re-exported from
  :mod:`~sigma_des.events.fast.primitives`;
* every ``sigma_des`` module a covered module imports, transitively (``from X import
  n`` covers the submodule ``X.n`` if there is one, else ``X``), at any indentation, so
  constants, callees and whatever computes them at import time are covered.

A package ``__init__`` is covered only when names are imported from it. A module that
is not imported by a covered one cannot reach a kernel's globals, so its edits keep
the cache (tests/cache/test_sources.py checks that every dispatcher's module is a
root).
"""

from __future__ import annotations

import hashlib
import os
import platform
import re
import sys
from pathlib import Path

__all__ = ["PACKAGE", "fingerprint", "kernel_sources"]

#: The ``sigma_des`` package directory.
PACKAGE = Path(__file__).resolve().parents[1]

_DECORATORS = (r"n?jit|vectorize|guvectorize|cfunc|stencil|intrinsic|generated_jit"
               r"|overload\w*|register_jitable")
# Each pattern starts with a literal, which ``re`` finds fast: 1.1 MB of source is
# scanned at every import (anchoring at line starts with re.M was 4x slower).
_NUMBA = re.compile(rb"\n(?:from|import)[ \t]+numba\b")
_DECORATOR = re.compile(rb"@(?:\w+\.)*(?:" + _DECORATORS.encode() + rb")\b")
# Docstring examples may match too: that only widens the covered set. Two patterns,
# each with a literal prefix, are 3x faster than one alternation.
_FROM = re.compile(rb"from[ \t]+(\.+[\w.]*|sigma_des[\w.]*)[ \t]+import[ \t]+"
                   rb"(\([^)]*\)|[^\n#]*)")
_IMPORT = re.compile(rb"import[ \t]+(sigma_des[^\n#]*)")


def _py_files(package: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` under ``package``."""
    out: dict[str, Path] = {}
    top = str(package)
    for d, dirs, names in os.walk(top):
        dirs[:] = [x for x in dirs if x != "__pycache__"]
        prefix = package.name + d[len(top):].replace(os.sep, ".")
        for n in names:
            if n.endswith(".py"):
                out[prefix if n == "__init__.py" else f"{prefix}.{n[:-3]}"] = Path(d, n)
    return out


def _is_root(src: bytes) -> bool:
    """True if ``src`` imports numba at module level or starts a line with a jit decorator."""
    if b"numba" in src and _NUMBA.search(src):
        return True
    for m in _DECORATOR.finditer(src):
        if not src[src.rfind(b"\n", 0, m.start()) + 1 : m.start()].strip():
            return True
    return False


def _names(clause: bytes) -> list[str]:
    """The imported names of an import clause (``a as b, c`` or ``(a, b)``)."""
    text = clause.decode("utf-8", "replace").strip("() \t\r\n")
    return [n.split()[0] for n in text.replace("\n", " ").split(",") if n.split()]


def _imports(mod: str, is_pkg: bool, src: bytes, modules: dict[str, Path]) -> set[str]:
    """The package's modules that module ``mod`` (source ``src``) imports."""
    pkg = mod.split(".") if is_pkg else mod.split(".")[:-1]
    found: set[str] = set()
    for clause in _IMPORT.findall(src):  # import a.b as c, d
        found.update(_names(clause))
    for spec_b, clause in _FROM.findall(src):
        spec = spec_b.decode()
        level = len(spec) - len(spec.lstrip("."))
        rest = [spec[level:]] if spec[level:] else []
        base = ".".join(pkg[: len(pkg) - level + 1] + rest) if level else spec
        for n in _names(clause):
            found.add(f"{base}.{n}" if f"{base}.{n}" in modules else base)
    return {f for f in found if f in modules}


def _scan(package: Path) -> dict[Path, bytes]:
    """The covered files (see the module docstring) and their bytes, sorted by path."""
    modules = _py_files(package)
    # the leading newline lets _NUMBA match an import on the first line
    src = {m: b"\n" + p.read_bytes() for m, p in modules.items()}
    todo = [m for m, s in src.items() if _is_root(s)]
    seen = set(todo)
    while todo:
        m = todo.pop()
        new = _imports(m, modules[m].name == "__init__.py", src[m], modules) - seen
        seen |= new
        todo += new
    return {modules[m]: src[m][1:] for m in sorted(seen, key=lambda m: modules[m])}


def kernel_sources(package: Path = PACKAGE) -> list[Path]:
    """Every file of ``package`` whose content can change compiled code, sorted.

    Args:
        package: the package directory (a parameter so tests can scan a copy).

    Returns:
        The roots (modules using numba) and their transitive imports within the package.
    """
    return list(_scan(package))


def fingerprint(package: Path = PACKAGE) -> str:
    """16 hex digits over :func:`kernel_sources` and the compiler's versions.

    Covers each file's path (relative to ``package``) and bytes, and the numba, numpy
    and Python versions and the machine type, which change the compiled code too
    (numba keys its index by signature and target, not by its own version).
    """
    import numba
    import numpy

    h = hashlib.sha256()
    for part in (numba.__version__, numpy.__version__, sys.version, platform.machine()):
        h.update(part.encode() + b"\0")
    for p, data in _scan(package).items():
        h.update(p.relative_to(package).as_posix().encode() + b"\0")
        h.update(data + b"\0")
    return h.hexdigest()[:16]
