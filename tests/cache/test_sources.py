"""The kernels' source set and fingerprint (issue 15): what an edit must, and must not, reset."""

from __future__ import annotations

import importlib
import shutil
import types
from pathlib import Path

from numba.core.dispatcher import Dispatcher

from sigma_des.cache.sources import PACKAGE, fingerprint, kernel_sources


def _copy(tmp: Path) -> Path:
    dst = tmp / "sigma_des"
    shutil.copytree(PACKAGE, dst, ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def _rel(paths: list[Path], pkg: Path) -> list[str]:
    return [p.relative_to(pkg).as_posix() for p in paths]


def test_a_copy_has_the_same_fingerprint_and_edits_of_covered_files_change_it(
        tmp_path: Path) -> None:
    pkg = _copy(tmp_path)
    fp = fingerprint(PACKAGE)
    assert len(fp) == 16 and int(fp, 16) >= 0
    assert fingerprint(pkg) == fp  # relative paths: the checkout's location does not count
    for rel in ("events/fast/layout.py", "events/fast/broker.py", "agents/layout.py",
                "net/kinds.py", "errors.py"):
        f = pkg / rel
        orig = f.read_bytes()
        f.write_bytes(orig + b"\n")
        assert fingerprint(pkg) != fp, rel
        f.write_bytes(orig)
        assert fingerprint(pkg) == fp


def test_edits_of_uncovered_files_keep_it(tmp_path: Path) -> None:
    pkg = _copy(tmp_path)
    fp = fingerprint(pkg)
    for rel in ("cli.py", "api.py", "config.py", "plots.py", "jitcache.py",
                "events/fast/driver.py", "warmup/units.py"):
        (pkg / rel).write_bytes((pkg / rel).read_bytes() + b"\n# edited\n")
        assert fingerprint(pkg) == fp, rel


def test_the_package_set_holds_the_fast_core_and_its_constants_not_the_front_end() -> None:
    got = set(_rel(kernel_sources(), PACKAGE))
    for rel in ("events/fast/compiler.py", "events/fast/layout.py", "events/fast/loop.py",
                "events/fast/broker.py", "events/fast/node.py", "events/fast/transport.py",
                "agents/kernel.py", "agents/layout.py", "core/counter_rng.py",
                "events/align/ring.py", "metrics/dtw.py", "net/kinds.py",
                "events/align/lockstep.py", "agents/rule_kernels.py", "metrics/tick_kernels.py"):
        assert rel in got, rel
    for rel in ("__init__.py", "api.py", "cli.py", "config.py", "jitcache.py",
                "cache/ideal.py", "warmup/units.py", "events/fast/driver.py"):
        assert rel not in got, rel
    # narrow: 36 of 173 files when written, 60 of 235 with session 14's kernels
    assert len(got) < 80


def _write(pkg: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        (pkg / rel).parent.mkdir(parents=True, exist_ok=True)
        (pkg / rel).write_text(text)


def test_roots_and_transitive_imports_on_a_synthetic_package(tmp_path: Path) -> None:
    pkg = tmp_path / "sigma_des"
    _write(pkg, {
        "__init__.py": "from sigma_des.front import run\n",
        "front.py": "from sigma_des.k import f\n",           # imports a root: not covered
        "k.py": '"""Doc."""\nfrom numba import njit\nfrom sigma_des.consts import (\n'
                "    A,\n    B as C,\n)\n\n@njit(cache=True)\ndef f():\n    return A\n",
        "consts.py": "import sigma_des.deep.values as v\nA = v.X\nB = 2\n",
        "deep/__init__.py": "",                             # only a submodule is imported
        "deep/values.py": "X = 1\n",
        "reexport.py": "from .k import f as jit\n",         # relative import of the root
        "user.py": "from sigma_des.reexport import jit\nfrom sigma_des import pkgconst\n\n"
                   "@jit\ndef g():\n    return 0\n",       # a decorator re-exported
        "pkgconst/__init__.py": "Y = 3\n",
        "lazy.py": "def h():\n    import numba\n    from sigma_des import front\n",
        "doc.py": '"""Mentions @njit in prose and `from sigma_des.front import run`."""\n',
    })
    assert _rel(kernel_sources(pkg), pkg) == [
        "consts.py", "deep/values.py", "k.py", "pkgconst/__init__.py", "reexport.py",
        "user.py"]


def _package_dispatchers() -> list[tuple[str, Dispatcher]]:
    out = []
    for p in sorted(PACKAGE.rglob("*.py")):
        parts = p.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        try:
            mod = importlib.import_module(name)
        except ImportError:  # an optional dependency (live mode, plots) is missing
            continue
        out += [(name, obj) for obj in vars(mod).values() if isinstance(obj, Dispatcher)]
    return out


def test_every_kernel_and_what_its_code_names_is_covered() -> None:
    """Each numba dispatcher of the package is defined in a covered file, and so is each
    package module or function its code reads from its globals (so the text scan
    misses no root and no callee)."""
    covered = {str(p) for p in kernel_sources()}
    found = _package_dispatchers()
    assert len({id(d) for _m, d in found}) > 50
    for _mod, d in found:
        fn = d.py_func
        assert fn.__code__.co_filename in covered, fn.__qualname__
        for name in fn.__code__.co_names:
            obj = fn.__globals__.get(name)
            if isinstance(obj, Dispatcher):
                obj = obj.py_func
            if isinstance(obj, types.ModuleType) and obj.__name__.startswith("sigma_des"):
                assert obj.__file__ in covered, (fn.__qualname__, name)
            elif isinstance(obj, types.FunctionType) and obj.__module__.startswith("sigma_des"):
                assert obj.__code__.co_filename in covered, (fn.__qualname__, name)
