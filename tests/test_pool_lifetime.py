"""The local executor's workers never outlive the caller (issue 26): SIGKILL of the
caller takes them along, an exception in the caller stops them at once, and the
terminal's Ctrl-C reaches only the caller."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from procs import gone, wait_gone

from sigma_des.pool import local_pool


def sleep_and_tell(d: str, i: int) -> int:
    """A worker call: write this worker's pid, then sleep (far longer than any test)."""
    Path(d, f"{i}.pid").write_text(str(os.getpid()))
    try:
        time.sleep(600)
    finally:  # a KeyboardInterrupt would end the call here
        Path(d, f"{i}.end").write_text("")
    return i


def _pids(d: Path, n: int, limit: float = 120.0) -> list[int]:
    end = time.monotonic() + limit
    while len(list(d.glob("*.pid"))) < n:
        assert time.monotonic() < end, "the workers never started"
        time.sleep(0.05)
    time.sleep(0.1)  # the pid files are written whole
    return [int(f.read_text()) for f in sorted(d.glob("*.pid"))]


_CALLER = """
import sys, time
sys.path.insert(0, sys.argv[3])
from test_pool_lifetime import sleep_and_tell
from sigma_des.pool import local_pool
with local_pool(2, sys.argv[2] or None) as submit:
    list(submit(sleep_and_tell, [(sys.argv[1], 0), (sys.argv[1], 1)]))
"""


@pytest.mark.parametrize("method", ["fork", "spawn", "forkserver"])
def test_sigkill_of_the_caller_takes_the_workers_along(tmp_path: Path, method: str) -> None:
    p = subprocess.Popen([sys.executable, "-c", _CALLER, str(tmp_path), method,
                          str(Path(__file__).parent)])
    try:
        workers = _pids(tmp_path, 2)
    finally:
        p.kill()
        p.wait(timeout=60)
    assert wait_gone(workers), workers


def test_an_exception_in_the_caller_stops_the_running_workers(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError, match="stop"), local_pool(2) as submit:
        submit(sleep_and_tell, [(str(tmp_path), 0), (str(tmp_path), 1)])
        workers = _pids(tmp_path, 2)
        raise RuntimeError("stop")
    assert all(gone(w) for w in workers)  # terminated and reaped before the block ended


def test_workers_ignore_the_terminal_s_ctrl_c(tmp_path: Path) -> None:
    with local_pool(2) as submit:
        submit(sleep_and_tell, [(str(tmp_path), 0), (str(tmp_path), 1)])
        workers = _pids(tmp_path, 2)
        for w in workers:
            os.kill(w, signal.SIGINT)
        time.sleep(0.5)
        assert not any(gone(w) for w in workers)
        assert not list(tmp_path.glob("*.end"))  # the calls go on
        for w in workers:  # end the calls (they would sleep 600 s)
            os.kill(w, signal.SIGKILL)
