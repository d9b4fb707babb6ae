"""Importing with no writable cache location falls back to a temporary one (issue 9.11)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import sigma_des

ROOT = Path(sigma_des.__file__).resolve().parent


def _blocked_copy(tmp: Path) -> Path:
    """A copy of the package where every ``__pycache__`` is a file (so even root
    cannot cache there)."""
    dst = tmp / "site" / "sigma_des"
    shutil.copytree(ROOT, dst, ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    for d in [dst, *[p for p in dst.rglob("*") if p.is_dir()]]:
        (d / "__pycache__").write_text("not a directory")
    return dst


def _env(tmp: Path, home: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "XDG_"))}
    env.update(PYTHONPATH=str(tmp / "site"), HOME=str(home), TMPDIR=str(tmp / "t"),
               PYTHONDONTWRITEBYTECODE="1")
    (tmp / "t").mkdir(exist_ok=True)
    return env


@pytest.mark.skipif(sys.platform != "linux", reason="HOME-based cache paths")
def test_import_without_any_writable_cache_location(tmp_path: Path) -> None:
    _blocked_copy(tmp_path)
    home = tmp_path / "home-is-a-file"
    home.write_text("")
    code = (
        "import numpy as np, sigma_des, os\n"
        "from sigma_des.events.align.ring import RingBuffers\n"
        "b = RingBuffers(2, 4, 1)\n"
        "print(b.insert([0, 1], [3, 5], [0.1, 0.2], [[1.0], [2.0]]).tolist())\n"
        "print(os.environ['NUMBA_CACHE_DIR'])\n"
        "print(sigma_des.__file__)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], env=_env(tmp_path, home),
                       capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = r.stdout.splitlines()
    assert out[0] == "[True, True]"
    assert out[2].startswith(str(tmp_path))
    assert out[1] == str(tmp_path / "t" / f"sigma_des-numba-{os.getuid()}")
    warn = [ln for ln in r.stderr.splitlines() if ln.startswith("sigma-des: warning:")]
    assert len(warn) == 1 and "caching compiled kernels in" in warn[0]
    assert any(Path(out[1]).rglob("*.nbi"))  # the kernel was cached there


def test_writable_tree_needs_no_fallback(tmp_path: Path) -> None:
    from sigma_des.jitcache import ensure_cache_dir

    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "m.py").write_text("")
    env = os.environ.pop("NUMBA_CACHE_DIR", None)
    try:
        assert ensure_cache_dir(pkg) is None
        assert "NUMBA_CACHE_DIR" not in os.environ
    finally:
        if env is not None:
            os.environ["NUMBA_CACHE_DIR"] = env
