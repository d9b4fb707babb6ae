"""The guard every command puts around its files and its memory.

One contract for ``replay``, ``tune``, the fitted-parameter files (and, through
:mod:`sigma_des.outputs`, ``compare`` and ``sweep``): a bad path costs nothing and
ends in one line naming the option.

* :func:`input_file` — an input exists, is a regular file and can be read;
  :func:`read_text` reads it as UTF-8 text or says it is not text.
* :func:`output_file` — an output path can be written **before** any work: not a
  directory, its folder exists (or is created) and accepts a new file.
* :func:`atomic_write` — the output is written under a temporary name in the same
  folder, flushed, fsynced and renamed into place, with the mode a plain ``open``
  would give under the process's umask (0644 under umask 022), so a full disk or a
  crash never leaves a truncated file under the final name.
* :func:`require_memory` — refuse work whose estimate exceeds the available memory
  unless forced.

Every failure is a :class:`~sigma_des.errors.ConfigError` whose key is the option
(``--out``, ``--log``…), so the CLI prints ``sigma-des: error: --out: …`` and exits 2.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from sigma_des.errors import ConfigError
from sigma_des.outputs import make_dir, umask

__all__ = [
    "atomic_write",
    "file_mode",
    "input_file",
    "output_file",
    "read_text",
    "require_memory",
]


def _why(e: OSError) -> str:
    return e.strerror or type(e).__name__


def _about(p: Path, key: str) -> str:
    """The file named in a message, unless the key already names it."""
    return "" if key == str(p) else f"{p}: "


def input_file(path: str | Path, key: str, what: str = "file") -> Path:
    """``path`` as an existing, readable regular file.

    Args:
        path: the input.
        key: the option named in the error (``--log``), or the file itself.
        what: what the file should be, for the message (``"CSV flight log"``).

    Raises:
        ConfigError: missing, a directory (or other non-file), or unreadable.
    """
    p = Path(path)
    at = _about(p, key)
    try:
        if p.is_dir():
            raise ConfigError(key, f"{at}is a directory, not a {what}")
        if not p.exists():
            raise ConfigError(key, f"{at}{what} not found")
        if not p.is_file():
            raise ConfigError(key, f"{at}not a regular file (a {what} is needed)")
        with p.open("rb") as fh:
            fh.read(1)
    except OSError as e:
        raise ConfigError(key, f"{at}cannot read: {_why(e)}") from None
    return p


def read_text(path: str | Path, key: str, what: str = "file") -> str:
    """The UTF-8 text of an input file checked by :func:`input_file`.

    Raises:
        ConfigError: the file cannot be read or is not UTF-8 text (the offset of the
            first undecodable byte is named).
    """
    p = input_file(path, key, what)
    at = _about(p, key)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise ConfigError(key, f"{at}cannot read: {_why(e)}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(
            key, f"{at}not a UTF-8 text {what} (undecodable byte at offset {e.start})"
        ) from None


def output_file(path: str | Path, key: str = "--out", force: bool = True) -> Path:
    """Check, before any work, that ``path`` can be written as a file.

    The folder is created if missing (and removed again if the command ends with it
    still empty: :func:`sigma_des.outputs.remove_unused`); a probe file is created and
    removed in it.

    Args:
        path: the output file.
        key: the option named in the error.
        force: allow replacing an existing file (else an existing file is an error).

    Raises:
        ConfigError: ``path`` is a directory, exists without ``force``, lies under a
            file, or its folder cannot be created or written.
    """
    p = Path(path)
    if p.is_dir():
        raise ConfigError(key, f"{p} is a directory; give a file path")
    if p.exists() and not force:
        raise ConfigError(key, f"{p}: exists; pass --force to overwrite it")
    for parent in p.parents:
        if parent.exists() and not parent.is_dir():
            raise ConfigError(key, f"{p} lies under {parent}, which is a file")
    d = p.parent
    try:
        make_dir(d)  # removed again if the command ends without writing into it
        fd, probe = tempfile.mkstemp(dir=d, prefix=f".{p.name}.", suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise ConfigError(key, f"cannot write {p}: {_why(e)}") from None
    return p


def file_mode() -> int:
    """The mode a new file gets from ``open`` under the current umask (0o666 & ~umask)."""
    return 0o666 & ~umask()


@contextlib.contextmanager
def _temporary(p: Path, binary: bool) -> Iterator[IO[Any]]:
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".part")
    try:
        fh: IO[Any] = os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", newline="")
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, file_mode())
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def atomic_write(
    path: str | Path, writer: Callable[[IO[Any]], None], key: str = "--out", binary: bool = False
) -> Path:
    """Write ``path`` all or nothing: temporary name, fsync, rename.

    Args:
        path: the final file (its folder must exist; see :func:`output_file`).
        writer: fills the open temporary file (text, or bytes if ``binary``).
        key: the option named in the error.
        binary: open the temporary file in binary mode.

    Returns:
        ``path``.

    Raises:
        ConfigError: any ``OSError`` while writing (disk full included); the
            temporary file is removed and nothing is left under ``path``'s name that
            was not there before.
    """
    p = Path(path)
    try:
        with _temporary(p, binary) as fh:
            writer(fh)
    except OSError as e:
        raise ConfigError(key, f"cannot write {p}: {_why(e)}") from None
    return p


def _gib(b: float) -> str:
    return f"{b / 2**30:.3g} GiB"


def require_memory(
    need: int, have: int | None, what: str, advice: str, force: bool = False
) -> int:
    """Refuse work estimated to need more than the available memory.

    Args:
        need: the estimate (bytes).
        have: the available memory (bytes; :func:`sigma_des.budget.available_bytes`),
            None if unknown (then nothing is refused).
        what: what needs it, for the message (``"replay at --rate 1e+09 Hz"``).
        advice: what the user can lower (``"lower --rate"``); ``or pass --force`` is
            appended.
        force: skip the refusal.

    Returns:
        ``need``.

    Raises:
        ConfigError: (key ``memory``) ``need`` exceeds the available memory.
    """
    if not force and have is not None and need > have:
        raise ConfigError(
            "memory",
            f"{what} needs about {_gib(need)}, but {_gib(have)} is available; "
            f"{advice}, or pass --force",
        )
    return need
