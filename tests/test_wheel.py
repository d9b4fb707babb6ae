"""The built wheel runs outside the checkout with its base dependencies only (issue 22.5).

Builds the wheel (``pip wheel``, build isolation from the local index), installs it into
a fresh venv with the same pip, and runs ``sigma-des --version`` and a tiny ``compare``
from an empty directory, as a user who typed ``pip install .`` would.

To stay cheap, the venv does not download its dependencies again: it sees, through a
``.pth`` file, a directory of links to exactly the installed distributions that the
wheel's *base* ``Requires-Dist`` needs (transitively, extras excluded) — not the test
venv's site-packages, whose extras (mcap, dask, jsbsim, paho, matplotlib, ...) and
editable checkout would hide a missing base dependency or a file left out of the wheel.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from importlib.metadata import Distribution, distribution
from pathlib import Path

import pytest
from packaging.requirements import Requirement

CHECKOUT = Path(__file__).resolve().parents[1]


def _requires(dist: Distribution, extra: str = "") -> list[Requirement]:
    """``dist``'s requirements that apply without extras (markers evaluated here)."""
    out = []
    for line in dist.requires or []:
        req = Requirement(line)
        if req.marker is None or req.marker.evaluate({"extra": extra}):
            out.append(req)
    return out


def _closure(reqs: list[Requirement]) -> dict[str, Distribution]:
    """The installed distributions ``reqs`` need, transitively, by normalised name."""
    seen: dict[str, Distribution] = {}
    todo = list(reqs)
    while todo:
        req = todo.pop()
        key = req.name.lower().replace("_", "-")
        if key in seen:
            continue
        dist = distribution(req.name)
        seen[key] = dist
        todo += _requires(dist)
        for extra in req.extras:  # e.g. dask[distributed]: not in the base set, kept general
            todo += [r for r in _requires(dist, extra) if r not in _requires(dist)]
    return seen


def _link_closure(dists: dict[str, Distribution], into: Path) -> None:
    """Symlink every top-level entry (package, module, .libs, dist-info) of ``dists``."""
    into.mkdir()
    site = Path(sysconfig.get_paths()["purelib"])
    for dist in dists.values():
        tops = {f.parts[0] for f in dist.files or [] if f.parts and f.parts[0] != ".."}
        for top in sorted(tops):
            src = site / top
            if src.exists() and not (into / top).exists():
                (into / top).symlink_to(src)


@pytest.mark.early  # ~1 CPU-minute: building, and compiling every kernel of the fresh install
def test_the_wheel_runs_from_an_empty_directory_with_base_dependencies(tmp_path: Path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(CHECKOUT / name, src / name)
    # the lab sits beside the package as in the checkout, so a package list that took
    # it in would show below
    for folder in ("sigma_des", "lab"):
        shutil.copytree(CHECKOUT / folder, src / folder,
                        ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run([*pip, "wheel", "--no-deps", "-w", str(tmp_path / "dist"), f"{src}/"],
                   check=True, capture_output=True, timeout=600)
    (wheel,) = (tmp_path / "dist").glob("sigma_des-*.whl")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        meta = z.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert {"sigma_des/py.typed", "sigma_des/scenarios/latency_tolerance.toml",
            "sigma_des/calibrate/residuals.toml",  # predict's residuals
            "sigma_des/record/foxglove_layout.json"} <= names  # the Foxglove layout
    lab = sorted(n for n in names if n.startswith(("sigma_lab/", "lab/"))
                 or n.startswith(("sigma_des/studies/", "sigma_des/reference/")))
    assert lab == [], f"the wheel ships the lab: {lab[:5]}"
    assert "sigma_des/calibrate/fit.py" in names
    base = [Requirement(ln.split(":", 1)[1]) for ln in meta.splitlines()
            if ln.startswith("Requires-Dist:")]
    base = [r for r in base if r.marker is None or r.marker.evaluate({"extra": ""})]
    assert "numba" in {r.name for r in base}

    venv = tmp_path / "v"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True,
                   timeout=120)
    py = venv / "bin" / "python"
    subprocess.run([*pip, "--python", str(py), "install", "--no-deps", "--no-index", str(wheel)],
                   check=True, capture_output=True, timeout=300)
    deps = tmp_path / "deps"
    _link_closure(_closure(base), deps)
    site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()"
                           "['purelib'])"], check=True, capture_output=True, text=True).stdout
    (Path(site.strip()) / "base_deps.pth").write_text(f"{deps}\n")

    empty = tmp_path / "empty"
    empty.mkdir()
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("PYTHON", "NUMBA_", "SIGMA_DES_", "XDG_", "VIRTUAL_ENV"))}
    # NUMBA_OPT=0: the fresh install compiles every kernel (no cache fits its paths); the
    # lowest LLVM optimisation level halves that, and the run is tiny
    env.update(HOME=str(tmp_path / "home"), XDG_CACHE_HOME=str(tmp_path / "cache"), NUMBA_OPT="0",
               PATH=f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}")
    exe = str(venv / "bin" / "sigma-des")
    r = subprocess.run([exe, "--version"], cwd=empty, env=env, capture_output=True, text=True,
                       timeout=120)
    assert (r.returncode, r.stdout.strip()) == (0, "sigma-des 0.1.0"), r.stderr
    r = subprocess.run([str(py), "-c", "import importlib.util, sigma_des; "
                        "print(sigma_des.__file__, importlib.util.find_spec('mcap') is not None)"],
                       cwd=empty, env=env, capture_output=True, text=True, timeout=120)
    where, has_extra = r.stdout.split()
    assert where.startswith(str(venv)) and has_extra == "False"  # the wheel, no extras
    r = subprocess.run([exe, "compare", "--set", "nodes=10", "--set", "duration=0.5",
                        "--no-progress"], cwd=empty, env=env, capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr[-2000:]
    lines = r.stdout.splitlines()
    assert [ln.split()[0] for ln in lines[1:5]] == ["none", "lockstep", "hlc", "bides"]
    assert list(empty.iterdir()) == []  # compare without --out writes nothing here
