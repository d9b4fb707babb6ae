"""A newcomer's first run: the compile is announced, and no progress frames go to a log."""

from __future__ import annotations

from pathlib import Path

import pytest

from sigma_des import jitcache, load
from sigma_des.api import compare
from sigma_des.cache.sources import fingerprint
from sigma_des.cli import main

NOTICE = "compiling kernels once (~1 min; `sigma-des warmup` does it ahead)"


def test_kernels_cached_reads_the_fingerprint_directory(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert not jitcache.kernels_cached()  # no directory yet
    d = tmp_path / "numba" / fingerprint(jitcache.PACKAGE) / "core_abc"
    d.mkdir(parents=True)
    assert not jitcache.kernels_cached()  # a directory without an index is not a cache
    (d / "step.step-12.py311.nbi").write_bytes(b"")
    assert jitcache.kernels_cached()


@pytest.mark.parametrize("cached", [False, True])
def test_compare_says_when_it_will_compile(cached: bool, monkeypatch: pytest.MonkeyPatch,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(jitcache, "kernels_cached", lambda: cached)
    assert main(["compare", "--set", "nodes=3", "--set", "duration=0.2", "--methods", "none",
                 "--no-progress"]) == 0
    assert (NOTICE in capsys.readouterr().err) is (not cached)


def test_no_progress_frames_when_stderr_is_not_a_terminal(
        capsys: pytest.CaptureFixture[str]) -> None:
    """tqdm's bar writes ``\\r`` frames; with a captured (non-terminal) stderr it stays off."""
    compare(load(None, ["nodes=3", "duration=0.3"]), ["none", "bides"], progress=True)
    assert "\r" not in capsys.readouterr().err
