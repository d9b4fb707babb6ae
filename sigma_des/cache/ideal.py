"""On-disk cache of the ideal fidelity run, shared by methods, processes and runs.

The ideal run (zero latency, perfect alignment: :func:`sigma_des.agents.ideal.fly`)
is the same for every alignment method of a scenario, so it is computed once and
kept as one ``.npz`` file per scenario under :func:`cache_dir`:

* ``$SIGMA_DES_CACHE_DIR/ideal/`` if that variable is set (``off``, ``0`` or the
  empty string switch the cache off: every call computes);
* else ``$XDG_CACHE_HOME/sigma_des/ideal/``, else ``~/.cache/sigma_des/ideal/``.

The file name is a key over everything the run could depend on: the whole resolved
scenario but its method list and engine (the seed included, so nothing relies on the
ideal run being seed-free), the contents of the ``dynamics_params`` file, the package
version, a fingerprint of the package's source files (so an edited checkout never
reads a stale entry although ``__version__`` is unchanged), and the numpy, numba and
Python versions and the machine type (the compiled kernels' floats). A hit returns
the very arrays that were computed (float64, bit-identical).

Writers are safe to run concurrently: each writes a private temporary file in the
cache directory and renames it over the entry (``os.replace`` is atomic on POSIX), so
a reader sees either no entry or a complete one. On a miss the computing process holds
an exclusive ``flock`` on ``<key>.lock`` (POSIX), so processes that miss the same key at
once (the methods of a sweep point on several workers) wait for the first one and read
its entry instead of flying the same run again. An entry that cannot be read (truncated,
foreign) counts as a miss and is rewritten. The directory can be deleted at any time.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import struct
import sys
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from sigma_des.cache.paths import ENV_VAR, root
from sigma_des.config import Scenario, to_dict
from sigma_des.outputs import temp_file
from sigma_des.version import __version__

__all__ = ["ENV_VAR", "EntryRows", "cache_dir", "cache_key", "cached", "cached_rows",
           "code_fingerprint"]

Arrays = tuple[NDArray[np.float64], NDArray[np.float64]]
Hit = TypeVar("Hit")


def cache_dir() -> Path | None:
    """The directory of ideal-run entries, or None when the cache is switched off."""
    r = root()
    return None if r is None else r / "ideal"


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """SHA-256 over the package's ``.py`` sources (relative path and bytes, sorted)."""
    pkg = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for p in sorted(pkg.rglob("*.py")):
        h.update(p.relative_to(pkg).as_posix().encode())
        h.update(b"\0")
        h.update(p.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


def _file_digest(path: str) -> str:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return "unreadable"


def cache_key(sc: Scenario) -> str:
    """The entry name of ``sc``'s ideal run (64 hex digits)."""
    import numba

    d = to_dict(sc)
    d.pop("methods")
    d.pop("engine")
    blob = {
        "scenario": d,
        "dynamics_params": _file_digest(sc.dynamics_params) if sc.dynamics_params else "",
        "version": __version__,
        "code": code_fingerprint(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "python": sys.version.split()[0],
        "machine": platform.machine(),
    }
    return hashlib.sha256(json.dumps(blob, sort_keys=True, default=str).encode()).hexdigest()


def _read(path: Path) -> Arrays | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            t, pos = z["t"], z["pos"]
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    if t.dtype != np.float64 or pos.dtype != np.float64 or pos.ndim != 3 or len(t) != len(pos):
        return None
    return t, pos


def _write(path: Path, t: NDArray[np.float64], pos: NDArray[np.float64]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temp_file(path.parent, prefix=f".{path.stem[:16]}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, t=t, pos=pos)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``path`` (created); no lock where flock is missing."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fh = path.open("a")
    except OSError:
        yield
        return
    with fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


def cached(sc: Scenario, compute: Callable[[Scenario], Arrays]) -> Arrays:
    """``compute(sc)``, read from the cache when an entry exists, else computed and stored.

    A cache directory that cannot be created or written only costs the store: the
    computed arrays are returned all the same.
    """
    return _entry(sc, compute, _read)


def _entry(
    sc: Scenario, compute: Callable[[Scenario], Arrays], read: Callable[[Path], Hit | None]
) -> Hit | Arrays:
    """``read`` of the entry when it exists, else ``compute(sc)``, stored (see :func:`cached`)."""
    d = cache_dir()
    if d is None:
        return compute(sc)
    key = cache_key(sc)
    path = d / f"{key}.npz"
    hit = read(path) if path.exists() else None
    if hit is not None:
        return hit
    with _locked(d / f"{key}.lock"):
        hit = read(path) if path.exists() else None  # written while we waited
        if hit is not None:
            return hit
        t, pos = compute(sc)
        try:
            _write(path, np.ascontiguousarray(t, dtype=np.float64),
                   np.ascontiguousarray(pos, dtype=np.float64))
        except OSError:
            pass
    return t, pos


class EntryRows:
    """The positions of a cache entry, read a block of samples at a time
    (:class:`~sigma_des.metrics.fidelity.Rows`): the ``pos`` member of the ``.npz``,
    which ``np.savez`` stores uncompressed, read in place, so a long run's ideal
    positions need not fit in memory. The bytes are those the entry holds (the very
    arrays computed).

    Raises:
        ValueError: the entry is not such a file (not a stored float64 ``(T, n, 3)``
            C-order array, or its times do not match).
        OSError, zipfile.BadZipFile, KeyError: it cannot be read.
    """

    def __init__(self, path: Path) -> None:
        with zipfile.ZipFile(path) as z:
            info = z.getinfo("pos.npy")
            with z.open("t.npy") as ft:
                self.times = np.lib.format.read_array(ft, allow_pickle=False)
        if info.compress_type != zipfile.ZIP_STORED:
            raise ValueError("compressed entry")
        fh = path.open("rb")
        try:
            fh.seek(info.header_offset)
            local = fh.read(30)
            if local[:4] != b"PK\x03\x04":
                raise ValueError("not a zip member header")
            name_len, extra_len = struct.unpack("<HH", local[26:30])
            fh.seek(info.header_offset + 30 + name_len + extra_len)
            version = np.lib.format.read_magic(fh)
            read_header = {(1, 0): np.lib.format.read_array_header_1_0,
                           (2, 0): np.lib.format.read_array_header_2_0}.get(version)
            if read_header is None:
                raise ValueError(f"npy format {version}")
            shape, fortran, dtype = read_header(fh)
            if (fortran or dtype != np.dtype("<f8") or len(shape) != 3
                    or self.times.dtype != np.float64 or len(self.times) != shape[0]):
                raise ValueError("not a (T, n, 3) float64 entry")
        except BaseException:
            fh.close()
            raise
        self._fh, self._data = fh, fh.tell()
        self.shape: tuple[int, ...] = tuple(shape)
        self._row = int(np.prod(shape[1:])) * 8

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, rows: slice, /) -> NDArray[np.float64]:
        start, stop, _ = rows.indices(len(self))
        k = max(0, stop - start)
        out = np.empty((k, *self.shape[1:]))
        self._fh.seek(self._data + start * self._row)
        got = self._fh.readinto(out.reshape(-1).view(np.uint8).data)
        if got != k * self._row:
            raise OSError(f"ideal-run entry: read {got} of {k * self._row} bytes")
        return out

    def close(self) -> None:
        """Close the entry's file."""
        self._fh.close()

    def __del__(self) -> None:
        fh = getattr(self, "_fh", None)
        if fh is not None:
            fh.close()


def _rows(path: Path) -> EntryRows | None:
    try:
        return EntryRows(path)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None


def cached_rows(
    sc: Scenario, compute: Callable[[Scenario], Arrays]
) -> tuple[NDArray[np.float64], EntryRows | NDArray[np.float64]]:
    """:func:`cached`, with the positions of an entry as :class:`EntryRows` (read a
    block at a time) instead of one array: ``(times, positions)``. Computed here (a
    miss, or the cache off), the positions are the array in hand."""
    got = _entry(sc, compute, _rows)
    if isinstance(got, EntryRows):
        return got.times, got
    return got
