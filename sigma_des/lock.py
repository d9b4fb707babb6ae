"""An exclusive lock on an output (a recording, an ``--out`` folder) for one run.

Two runs writing the same recording or the same folder at once would interleave or
overwrite each other's files, and each would then report its results as written.
:class:`OutputLock` takes a non-blocking ``flock`` on a hidden lock file next to the
output; a second run is refused at once, naming the option and the process holding
it. The lock file holds that process id and is removed when the lock is released (a
run killed with SIGKILL leaves it behind, unlocked: the next run takes it over).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from pathlib import Path

from sigma_des.errors import ConfigError

__all__ = ["OutputLock"]


class OutputLock:
    """An exclusive, non-blocking lock of ``path`` (a lock file) for ``what``.

    Args:
        path: the lock file.
        key: the option named when the lock is held by another run.
        what: the output it guards (named in that message).

    Raises:
        ConfigError: another process holds the lock (on construction).
    """

    def __init__(self, path: Path, key: str, what: str) -> None:
        self.path = path
        self._fd: int | None = None
        while self._fd is None:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "?"
                os.close(fd)
                raise ConfigError(key, f"{what} is being written by another run (process "
                                       f"{holder}); wait for it to end, or write elsewhere"
                                  ) from None
            try:  # the file we locked may have been released and removed meanwhile
                same = os.stat(path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
            self._fd = fd

    def release(self) -> None:
        """Remove the lock file and release the lock (a second call does nothing)."""
        if self._fd is None:
            return
        with contextlib.suppress(OSError):
            self.path.unlink()
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> OutputLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()
