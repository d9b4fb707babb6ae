"""Whether processes are gone (tests of processes that must die with their parent)."""

from __future__ import annotations

import os
import time


def gone(pid: int) -> bool:
    """``pid`` has ended (a zombie waiting for its new parent to reap it counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] == "Z"
    except FileNotFoundError:
        return True


def wait_gone(pids: list[int], limit: float = 30.0) -> bool:
    """Poll until every pid is gone or ``limit`` s passed (a bound, not a speed target)."""
    end = time.monotonic() + limit
    while not all(gone(p) for p in pids) and time.monotonic() < end:
        time.sleep(0.1)
    return all(gone(p) for p in pids)
