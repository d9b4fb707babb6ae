"""numba's cache directory: ``<root>/numba/<fingerprint>``, chosen at import (issues 9.11, 15)."""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from numba.core import config

import sigma_des
from sigma_des.cache.sources import fingerprint
from sigma_des.jitcache import cache_root, ensure_cache_dir, prune

ROOT = Path(sigma_des.__file__).resolve().parent
FP = fingerprint()

_PROBE = ("import os, numba, sigma_des\n"
          "from sigma_des.events.fast import loop\n"
          "print(numba.config.CACHE_DIR)\n"
          "print(os.environ['NUMBA_CACHE_DIR'])\n"
          "print(loop.advance.stats.cache_path)\n")


def _env(tmp: Path, **extra: str) -> dict[str, str]:
    """The environment without numba's, XDG's or the package's cache variables."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("NUMBA_", "XDG_", "SIGMA_DES_"))}
    env.update(PYTHONDONTWRITEBYTECODE="1", TMPDIR=str(tmp / "t"), **extra)
    (tmp / "t").mkdir(exist_ok=True)
    return env


def _probe(env: dict[str, str], cwd: Path) -> list[str]:
    r = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True,
                       timeout=300, cwd=cwd, check=True)
    return r.stdout.splitlines()


@pytest.mark.parametrize("var", ["NUMBA_CACHE_DIR", "SIGMA_DES_CACHE_DIR"])
def test_a_subprocess_caches_under_the_root_by_fingerprint(tmp_path: Path, var: str) -> None:
    """The user's root (numba's or the package's variable) gets ``numba/<fingerprint>``,
    the root is exported for children, and a kernel's cache lives below the directory."""
    root = tmp_path / "root"
    env = _env(tmp_path, PYTHONPATH=str(ROOT.parent), **{var: str(root)})
    out = _probe(env, tmp_path)
    want = str(root / "numba" / FP)
    assert out[0] == want
    assert out[1] == str(root)
    assert out[2].startswith(want + os.sep + "fast_")
    assert sorted(p.name for p in (root / "numba").iterdir()) == [".prune.lock", FP]


def test_editing_a_constant_module_of_a_copy_moves_its_processes_to_a_new_directory(
        tmp_path: Path) -> None:
    """The issue's trap: ``events/fast/layout.py`` defines no kernel, yet after an edit a
    new process must not use the kernels compiled before it."""
    pkg = tmp_path / "site" / "sigma_des"
    shutil.copytree(ROOT, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    env = _env(tmp_path, PYTHONPATH=str(pkg.parent), NUMBA_CACHE_DIR=str(tmp_path / "nb"))
    before = _probe(env, tmp_path)[0]
    layout = pkg / "events" / "fast" / "layout.py"
    layout.write_text(layout.read_text() + "\n# edited\n")
    after = _probe(env, tmp_path)[0]
    assert before == str(tmp_path / "nb" / "numba" / FP)
    assert after == str(tmp_path / "nb" / "numba" / fingerprint(pkg)) and after != before
    assert (tmp_path / "nb" / "numba" / FP).is_dir()  # used a moment ago: not pruned


def test_cache_root_order(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for k in ("NUMBA_CACHE_DIR", "SIGMA_DES_CACHE_DIR", "XDG_CACHE_HOME"):
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "h"))
    assert cache_root() == tmp_path / "h" / ".cache" / "sigma_des"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "x"))
    assert cache_root() == tmp_path / "x" / "sigma_des"
    for off in ("off", "0", ""):  # the ideal-run cache off: kernels use the default root
        monkeypatch.setenv("SIGMA_DES_CACHE_DIR", off)
        assert cache_root() == tmp_path / "x" / "sigma_des"
    monkeypatch.setenv("SIGMA_DES_CACHE_DIR", str(tmp_path / "s"))
    assert cache_root() == tmp_path / "s"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "n"))
    assert cache_root() == tmp_path / "n"


def _blocked_copy(tmp: Path) -> Path:
    """A copy of the package whose ``__pycache__`` are files (numba's in-tree cache is
    impossible even for root)."""
    dst = tmp / "site" / "sigma_des"
    shutil.copytree(ROOT, dst, ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    for d in [dst, *[p for p in dst.rglob("*") if p.is_dir()]]:
        (d / "__pycache__").write_text("not a directory")
    return dst


@pytest.mark.skipif(sys.platform != "linux", reason="HOME-based cache paths")
def test_import_without_any_writable_cache_location(tmp_path: Path) -> None:
    _blocked_copy(tmp_path)
    home = tmp_path / "home-is-a-file"
    home.write_text("")
    env = _env(tmp_path, PYTHONPATH=str(tmp_path / "site"), HOME=str(home))
    r = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = r.stdout.splitlines()
    tmp_root = tmp_path / "t" / f"sigma_des-numba-{os.getuid()}"
    assert out[:2] == [str(tmp_root / "numba" / FP), str(tmp_root)]
    warn = [ln for ln in r.stderr.splitlines() if ln.startswith("sigma-des: warning:")]
    assert warn == [f"sigma-des: warning: cannot write numba's cache in "
                    f"{home / '.cache' / 'sigma_des'}; caching compiled kernels in {tmp_root}"]


def _dirs(parent: Path, ages: dict[str, float], now: float) -> None:
    for name, age in ages.items():
        (parent / name).mkdir(parents=True)
        (parent / name / "k.nbi").write_text("x")
        os.utime(parent / name, (now - age, now - age))


def test_prune_keeps_the_current_the_newest_and_the_recently_used(tmp_path: Path) -> None:
    now = 1_000_000.0
    names = [f"{i:016x}" for i in range(6)]
    # ages (s): 0 current; 1, 2 newest kept; 3 recent (within grace); 4, 5 old
    _dirs(tmp_path, dict(zip(names, [9e9, 10.0, 20.0, 50.0, 500.0, 900.0], strict=True)), now)
    (tmp_path / "not-a-fingerprint").mkdir()
    os.utime(tmp_path / "not-a-fingerprint", (0, 0))
    removed = prune(tmp_path, names[0], keep=2, grace_s=100.0, now=now)
    assert removed == [names[4], names[5]]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        ".prune.lock", *names[:4], "not-a-fingerprint"]


def test_prune_skips_while_another_process_holds_the_lock(tmp_path: Path) -> None:
    now = 1_000_000.0
    names = [f"{i:016x}" for i in range(3)]
    _dirs(tmp_path, dict(zip(names, [0.0, 500.0, 900.0], strict=True)), now)
    with (tmp_path / ".prune.lock").open("a") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        assert prune(tmp_path, names[0], keep=0, grace_s=0.0, now=now) == []
    assert prune(tmp_path, names[0], keep=0, grace_s=0.0, now=now) == names[1:]


@pytest.fixture
def numba_root(tmp_path: Path) -> Iterator[Path]:
    """``NUMBA_CACHE_DIR`` set to ``tmp_path``; after the test, the variable and numba's
    configuration (which ensure_cache_dir re-reads) as they were."""
    env, before = os.environ.get("NUMBA_CACHE_DIR"), config.CACHE_DIR  # type: ignore[attr-defined]
    os.environ["NUMBA_CACHE_DIR"] = str(tmp_path)
    yield tmp_path
    if env is None:
        os.environ.pop("NUMBA_CACHE_DIR")
    else:
        os.environ["NUMBA_CACHE_DIR"] = env
    config.reload_config()
    config.CACHE_DIR = before  # type: ignore[attr-defined]


def test_a_new_fingerprint_directory_prunes_old_ones(numba_root: Path) -> None:
    parent = numba_root / "numba"
    old = [f"{i:016x}" for i in range(5)]
    now = os.path.getmtime(numba_root)
    _dirs(parent, dict(zip(old, [4e4, 5e4, 6e4, 7e4, 8e4], strict=True)), now)
    assert FP not in old
    assert ensure_cache_dir() == str(parent / FP)
    assert config.CACHE_DIR == str(parent / FP)  # type: ignore[attr-defined]
    assert sorted(p.name for p in parent.iterdir()) == sorted([".prune.lock", FP, *old[:3]])
    # the directory exists now: a second import prunes nothing, even past the grace
    os.utime(parent / old[0], (0, 0))
    assert ensure_cache_dir() == str(parent / FP)
    assert (parent / old[0]).is_dir()
