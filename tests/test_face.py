"""The package face has no side effects; the command line starts light (issue 23, "A face
without side effects")."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import sigma_des
from sigma_des.cache.sources import fingerprint

ROOT = Path(sigma_des.__file__).resolve().parent
CORE = sorted(f"sigma_des.core.{p.stem}" for p in (ROOT / "core").glob("*.py")
              if p.stem not in ("__init__", "counter_rng"))  # counter_rng: numba's copy

# Imports the modules named on the command line and prints what got loaded.
_PROBE = """
import importlib, json, sys
for m in sys.argv[1:]:
    importlib.import_module(m)
print(json.dumps(sorted(sys.modules)))
"""


def _clean_env(home: Path) -> dict[str, str]:
    """A user with an empty HOME and cache: no numba, XDG or package cache variables."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("NUMBA_", "XDG_", "SIGMA_DES_"))}
    home.mkdir(exist_ok=True)
    env.update(HOME=str(home), XDG_CACHE_HOME=str(home / "xdg-cache"), PYTHONDONTWRITEBYTECODE="1")
    return env


def _loaded(tmp_path: Path, *modules: str) -> set[str]:
    r = subprocess.run([sys.executable, "-c", _PROBE, *modules], env=_clean_env(tmp_path / "h"),
                       cwd=tmp_path, capture_output=True, text=True, timeout=120, check=True)
    return set(json.loads(r.stdout))


def _tree(d: Path) -> list[str]:
    return sorted(str(p.relative_to(d)) for p in d.rglob("*"))


def test_import_sigma_des_imports_no_numba_and_creates_no_directory(tmp_path: Path) -> None:
    loaded = _loaded(tmp_path, "sigma_des")
    assert not {m for m in loaded if m.split(".")[0] in ("numba", "scipy", "numpy", "simpy")}
    ours = {m for m in loaded if m.startswith("sigma_des")}
    assert ours <= {"sigma_des", "sigma_des.version", "sigma_des.jitcache", "sigma_des.cache",
                    "sigma_des.cache.paths", "sigma_des.cache.sources"}, ours
    assert _tree(tmp_path) == ["h"]  # nothing under HOME, no ~/.cache, no XDG cache


@pytest.mark.parametrize("module", ["sigma_des.config", "sigma_des.cli", "sigma_des.errors",
                                    "sigma_des.loading", "sigma_des.outputs", *CORE])
def test_ground_floor_and_scenario_modules_import_no_numba(tmp_path: Path, module: str) -> None:
    loaded = _loaded(tmp_path, module)
    assert "numba" not in loaded
    assert "scipy" not in loaded  # imported where a draw needs it, not at start
    assert _tree(tmp_path) == ["h"]


def test_the_public_names_load_on_first_use() -> None:
    from sigma_des import METHODS, ConfigError, Scenario, compare, load

    assert Scenario.__module__ == "sigma_des.config" and load(None).nodes == 200
    assert compare.__module__ == "sigma_des.api" and "bides" in METHODS
    assert issubclass(ConfigError, ValueError)
    assert set(sigma_des.__all__) <= set(dir(sigma_des))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        sigma_des.nope  # noqa: B018


def test_help_and_version_load_no_command_module(tmp_path: Path) -> None:
    code = ("import json, sys\nfrom sigma_des.cli import main\n"
            "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
            "print(json.dumps(sorted(sys.modules)))")
    for argv in (["--help"], ["--version"]):
        r = subprocess.run([sys.executable, "-c", code, *argv], env=_clean_env(tmp_path / "h"),
                           capture_output=True, text=True, timeout=120, check=True)
        loaded = set(json.loads(r.stdout.splitlines()[-1]))
        ours = {m for m in loaded if m.startswith("sigma_des")}
        assert ours <= {"sigma_des", "sigma_des.version", "sigma_des.jitcache", "sigma_des.cli",
                        "sigma_des.errors", "sigma_des.cache", "sigma_des.cache.paths",
                        "sigma_des.cache.sources"}, ours
        assert "numpy" not in loaded


def test_help_is_plain_text_listing_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    from sigma_des.cli import COMMANDS, main

    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "``" not in out and ":mod:" not in out
    for name, cmd in COMMANDS.items():
        assert f"    {name}" in out
        assert cmd.help.split()[0] in out


def test_the_first_numba_import_sets_the_kernel_directory(tmp_path: Path) -> None:
    """Without numba imported first, the hook still points numba at ``<root>/numba/<fp>``
    before the first kernel is defined (the kernel's cache lives below it)."""
    code = ("import sigma_des, sys\nassert 'numba' not in sys.modules\n"
            "from sigma_des.events.fast import loop\nimport numba\n"
            "print(numba.config.CACHE_DIR)\nprint(loop.advance.stats.cache_path)\n")
    env = _clean_env(tmp_path / "h")
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=300, check=True)
    want = str(tmp_path / "h" / "xdg-cache" / "sigma_des" / "numba" / fingerprint())
    cache_dir, kernel_dir = r.stdout.splitlines()
    assert cache_dir == want
    assert kernel_dir.startswith(want + os.sep)
