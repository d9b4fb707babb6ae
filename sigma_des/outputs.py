"""Output directories and atomic file writes shared by ``compare`` and ``sweep``.

An output location is checked *before* a run (so a bad ``--out`` costs nothing),
and a set of files is written under temporary names and renamed into place only
once every one of them was written, so a failed write never leaves a
``results.csv`` without the ``summary.json`` that belongs to it.

Temporary files are made by :func:`temp_file`: ``mkstemp`` creates them ``0600``,
which ``os.replace`` would carry to the final name; they get the mode a plain
``open`` would give (``0666`` less the umask: ``0644`` under umask 022), so others on
a shared machine can read the results as the user's umask says.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import IO

from sigma_des.errors import ConfigError

__all__ = ["check_out_dir", "make_dir", "remove_unused", "temp_file", "umask", "write_files"]

#: The directories :func:`check_out_dir` created: (the directory, its topmost new parent).
_CREATED: list[tuple[Path, Path]] = []

#: A writer fills one open text file.
Writer = Callable[[IO[str]], None]


def umask() -> int:
    """The process's umask (read without changing it where ``/proc`` tells it)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    old = os.umask(0o022)  # no /proc (macOS): set and restore at once
    os.umask(old)
    return old


def temp_file(d: str | Path, prefix: str, suffix: str) -> tuple[int, str]:
    """``tempfile.mkstemp`` in ``d``, with the mode a new file gets from ``open``.

    Returns:
        ``(fd, path)``, as ``mkstemp``; rename the file into place with ``os.replace``.
    """
    fd, path = tempfile.mkstemp(dir=d, prefix=prefix, suffix=suffix)
    try:
        os.fchmod(fd, 0o666 & ~umask())
    except BaseException:
        os.close(fd)
        os.unlink(path)
        raise
    return fd, path


def check_out_dir(path: str | Path, key: str = "--out") -> Path:
    """Make sure ``path`` is (or can become) a writable directory; create it.

    Args:
        path: the output directory.
        key: the option or key named in the error message.

    Returns:
        The directory, created (with its missing parents) if it did not exist; what it
        created and is still empty when the command ends is removed
        (:func:`remove_unused`), so a refused or failed run leaves no empty folder.

    Raises:
        ConfigError: ``path`` is a file, lies under a file, or cannot be written.
    """
    d = Path(path)
    if d.exists() and not d.is_dir():
        raise ConfigError(key, f"{d} is an existing file, not a directory")
    for parent in d.parents:
        if parent.exists() and not parent.is_dir():
            raise ConfigError(key, f"{d} lies under {parent}, which is a file")
    try:
        make_dir(d)
        fd, probe = tempfile.mkstemp(dir=d, prefix=".probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise ConfigError(key, f"cannot write to directory {d}: {e.strerror or e}") from None
    return d


def make_dir(d: Path) -> None:
    """``d.mkdir(parents=True, exist_ok=True)``, noting what it created for
    :func:`remove_unused`.

    Raises:
        OSError: as ``mkdir``.
    """
    top = next((p for p in reversed((d, *d.parents)) if not p.exists()), None)
    d.mkdir(parents=True, exist_ok=True)
    if top is not None:
        _CREATED.append((d, top))


def remove_unused() -> None:
    """Remove the directories :func:`check_out_dir` created that are still empty (the
    command ended before writing into them), up to the topmost one it created."""
    while _CREATED:
        d, top = _CREATED.pop()
        p = d
        while True:
            try:
                p.rmdir()  # only an empty directory
            except OSError:
                break
            if p == top:
                break
            p = p.parent


@contextlib.contextmanager
def _temporaries(d: Path) -> Iterator[list[Path]]:
    made: list[Path] = []
    try:
        yield made
    except BaseException:
        for p in made:
            with contextlib.suppress(OSError):
                p.unlink()
        raise


def write_files(out_dir: str | Path, files: Mapping[str, Writer]) -> list[Path]:
    """Write every file of ``files`` into ``out_dir``, all or none.

    Each file is written to a temporary name in the same directory; only when all
    were written are they renamed to their final names (``os.replace`` is atomic).

    Args:
        out_dir: an existing, writable directory (see :func:`check_out_dir`).
        files: final file name -> function writing its content.

    Returns:
        The final paths, in the order of ``files``.

    Raises:
        ConfigError: a file could not be written (nothing of this call is left behind).
    """
    d = Path(out_dir)
    finals = [d / name for name in files]
    try:
        with _temporaries(d) as tmps:
            for name, writer in files.items():
                fd, tmp_name = temp_file(d, prefix=f".{name}.", suffix=".tmp")
                tmps.append(Path(tmp_name))
                with os.fdopen(fd, "w", newline="") as fh:
                    writer(fh)
            for tmp, final in zip(tmps, finals, strict=True):
                os.replace(tmp, final)
    except OSError as e:
        raise ConfigError("--out", f"cannot write {d}: {e.strerror or e}") from None
    return finals
