"""OutputLock: a second run writing the same output is refused at once, naming it."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from sigma_des.errors import ConfigError
from sigma_des.lock import OutputLock


def test_a_held_lock_refuses_a_second_holder_and_is_removed_on_release(tmp_path: Path) -> None:
    f = tmp_path / ".x.lock"
    with OutputLock(f, "--out", "x") as first:
        assert f.read_text() == f"{os.getpid()}\n"
        with pytest.raises(ConfigError) as ei:
            OutputLock(f, "--out", "x")  # another open file: flock refuses it
        assert ei.value.key == "--out"
        assert ei.value.reason == (f"x is being written by another run (process {os.getpid()}); "
                                   "wait for it to end, or write elsewhere")
        first.release()
        first.release()  # a second release does nothing
        assert not f.exists()
        with OutputLock(f, "--out", "x"):  # free again
            assert f.exists()
    assert not f.exists()


def test_a_lock_file_left_by_a_killed_run_is_taken_over(tmp_path: Path) -> None:
    f = tmp_path / ".x.lock"
    f.write_text("12345\n")  # SIGKILL leaves the file, never the lock
    with OutputLock(f, "--record", "x"):
        assert f.read_text() == f"{os.getpid()}\n"
