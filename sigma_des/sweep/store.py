"""Durable results store of a sweep: one SQLite row per run, written as runs finish.

The store is a single SQLite file in WAL mode with ``synchronous=FULL``: every
finished run is committed on its own, so a sweep killed at any point keeps every
run that had finished and loses only the ones in flight. Only the client process
(the one driving the sweep) opens it; Dask workers send their results back over
the wire and need no shared file system.

A run is keyed by ``(config_hash, seed, method)`` — the hash covers the whole
resolved scenario but its seed and method list (:func:`sigma_des.config.config_hash`),
so the same run reached from two different sweeps is stored once. ``attempts``
counts how many results for that key arrived (1 on first completion, +1 per retry).

Concurrent sweeps on one store share the work through *leases*: a sweep claims a
few runs at a time (a ``leases`` row naming its host, process and an expiry time),
runs them, and storing a result drops its lease. Another sweep skips runs under a
live lease; a lease dies when it expires or when its process (on the same host)
is gone, so a killed sweep's runs are claimed again at once.
"""

from __future__ import annotations

import json
import os
import socket
import sqlite3
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path
from types import TracebackType
from typing import Any

from sigma_des.errors import ConfigError

__all__ = ["STATUSES", "ResultStore", "RunKey"]

#: A run's key: (config hash, seed, method).
RunKey = tuple[str, int, str]

#: Status values of a stored run.
STATUSES: tuple[str, ...] = ("ok", "failed")

SCHEMA_VERSION = "1"

#: The first 16 bytes of every SQLite 3 database file.
_SQLITE_MAGIC = b"SQLite format 3\x00"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS configs (
    config_hash TEXT PRIMARY KEY,
    scenario    TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS runs (
    config_hash TEXT NOT NULL,
    seed        INTEGER NOT NULL,
    method      TEXT NOT NULL,
    status      TEXT NOT NULL CHECK (status IN ('ok', 'failed')),
    metrics     TEXT,
    wall        TEXT,
    links_mbps  TEXT,
    ts_summary  TEXT,
    error       TEXT,
    attempts    INTEGER NOT NULL DEFAULT 1,
    elapsed_s   REAL,
    worker      TEXT,
    version     TEXT,
    finished_at TEXT NOT NULL,
    PRIMARY KEY (config_hash, seed, method)
);
CREATE TABLE IF NOT EXISTS leases (
    config_hash TEXT NOT NULL,
    seed        INTEGER NOT NULL,
    method      TEXT NOT NULL,
    owner       TEXT NOT NULL,
    host        TEXT NOT NULL,
    pid         INTEGER NOT NULL,
    expires     REAL NOT NULL,
    PRIMARY KEY (config_hash, seed, method)
);
"""

_JSON_COLS = ("metrics", "wall", "links_mbps", "ts_summary")
_COLS = (
    "config_hash",
    "seed",
    "method",
    "status",
    *_JSON_COLS,
    "error",
    "attempts",
    "elapsed_s",
    "worker",
    "version",
    "finished_at",
)


_HOST = socket.gethostname()


def _alive(lease: tuple[str, str, int, float], now: float) -> bool:
    """A lease holds until it expires or, on this host, until its process is gone."""
    _owner, host, pid, expires = lease
    if expires < now:
        return False
    if host == _HOST:
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            return False
        except PermissionError:  # another user's live process
            return True
    return True


def _check_path(path: Path) -> bool:
    """Refuse a store path that cannot be a results store; True if the file exists.

    Raises:
        ConfigError: (key ``--store``) a directory, an empty file, a path under a
            file, or an unreadable file.
    """
    if path.is_dir():
        raise ConfigError("--store", f"{path} is a directory; give the path of a .sqlite file")
    if path.exists():
        if path.stat().st_size == 0:
            raise ConfigError(
                "--store", f"{path} is an empty file, not a results store; delete it to start "
                "a new store there"
            )
        if not os.access(path, os.R_OK | os.W_OK):
            raise ConfigError("--store", f"{path}: no permission to read and write it")
        with path.open("rb") as fh:
            head = fh.read(len(_SQLITE_MAGIC))
        if head != _SQLITE_MAGIC:
            raise ConfigError(
                "--store", f"{path} is not a sigma-des results store (not an SQLite file); "
                "give another path or move the file away"
            )
        return True
    for parent in path.parents:
        if parent.exists() and not parent.is_dir():
            raise ConfigError("--store", f"{path} lies under {parent}, which is a file")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ConfigError("--store", f"cannot create {path.parent}: {e.strerror or e}") from None
    return False


class ResultStore:
    """SQLite store of finished runs (see the module docstring).

    Args:
        path: the SQLite file (created with its parent directory if missing).

    Use as a context manager, or call :meth:`close`.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        existed = _check_path(self.path)
        try:
            self._db = sqlite3.connect(self.path, isolation_level=None, timeout=30.0)
        except sqlite3.Error as e:
            raise ConfigError("--store", f"cannot open {self.path}: {e}") from None
        try:
            self._open(existed)
        except sqlite3.DatabaseError as e:
            self._db.close()
            raise ConfigError(
                "--store", f"{self.path} is not a sigma-des results store (SQLite: {e}); "
                "give another path or move the file away"
            ) from None
        except BaseException:
            self._db.close()
            raise

    def _open(self, existed: bool) -> None:
        if existed:  # an existing file must be an intact SQLite database
            bad = self._db.execute("PRAGMA quick_check").fetchone()
            if bad is None or bad[0] != "ok":
                raise sqlite3.DatabaseError(f"integrity check failed: {bad and bad[0]}")
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=FULL")
        self._db.executescript(_SCHEMA)  # idempotent; executescript manages its own commit
        with self._tx():
            row = self._db.execute("SELECT value FROM meta WHERE key='schema'").fetchone()
            if row is None:
                self._db.execute("INSERT INTO meta VALUES ('schema', ?)", (SCHEMA_VERSION,))
            elif row[0] != SCHEMA_VERSION:
                raise ConfigError(
                    "--store",
                    f"{self.path}: results store schema {row[0]}, expected {SCHEMA_VERSION}",
                )

    # ------------------------------------------------------------ plumbing

    @contextmanager
    def _tx(self) -> Iterator[None]:
        """One immediate transaction: committed on success, rolled back on error."""
        self._db.execute("BEGIN IMMEDIATE")
        try:
            yield
        except BaseException:
            self._db.execute("ROLLBACK")
            raise
        self._db.execute("COMMIT")

    def close(self) -> None:
        """Close the database connection."""
        self._db.close()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # ------------------------------------------------------------ writing

    def put_config(self, config_hash: str, scenario: dict[str, Any]) -> None:
        """Record the resolved scenario behind ``config_hash`` (once)."""
        with self._tx():
            self._db.execute(
                "INSERT OR IGNORE INTO configs VALUES (?, ?)",
                (config_hash, json.dumps(scenario, sort_keys=True, default=str)),
            )

    def put(self, key: RunKey, status: str, payload: dict[str, Any]) -> None:
        """Store one finished run (committed before returning).

        Args:
            key: (config hash, seed, method).
            status: ``ok`` or ``failed``.
            payload: ``metrics``, ``wall``, ``links_mbps``, ``ts_summary`` (dicts),
                ``error`` (text), ``elapsed_s``, ``worker``, ``version``; all optional.
        """
        if status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {status!r}")
        vals: dict[str, Any] = {
            "config_hash": key[0],
            "seed": int(key[1]),
            "method": key[2],
            "status": status,
            **{c: _dumps(payload.get(c)) for c in _JSON_COLS},
            "error": payload.get("error"),
            "attempts": 1,
            "elapsed_s": payload.get("elapsed_s"),
            "worker": payload.get("worker"),
            "version": payload.get("version"),
            "finished_at": datetime.now(UTC).isoformat(timespec="seconds"),
        }
        cols = ", ".join(_COLS)
        marks = ", ".join(f":{c}" for c in _COLS)
        update = ", ".join(
            f"{c}=excluded.{c}" for c in _COLS if c not in ("config_hash", "seed", "method")
        ).replace("attempts=excluded.attempts", "attempts=runs.attempts + 1")
        with self._tx():
            self._db.execute(
                f"INSERT INTO runs ({cols}) VALUES ({marks}) "
                f"ON CONFLICT (config_hash, seed, method) DO UPDATE SET {update}",
                vals,
            )
            self._db.execute(
                "DELETE FROM leases WHERE config_hash=? AND seed=? AND method=?",
                (key[0], int(key[1]), key[2]),
            )

    # ------------------------------------------------------------ leases

    def claim(
        self, keys: Iterable[RunKey], owner: str, timeout: float, limit: int,
        retry_failed: bool = False,
    ) -> list[RunKey]:
        """Claim up to ``limit`` of ``keys`` for ``owner``, in one transaction.

        A key is claimable if it has no stored result (or a failed one and
        ``retry_failed``) and no live lease of another owner: a lease is dead once it
        expired or when its process (on this host) no longer exists.

        Args:
            keys: candidate runs, in the order to claim them.
            owner: the claiming sweep's unique name.
            timeout: seconds the new leases last.
            limit: most keys to claim.
            retry_failed: failed runs may be claimed too.

        Returns:
            The keys claimed (leases written), in order.
        """
        now = time.time()
        got: list[RunKey] = []
        with self._tx():
            for k in keys:
                if len(got) >= limit:
                    break
                key = (k[0], int(k[1]), k[2])
                row = self._db.execute(
                    "SELECT status FROM runs WHERE config_hash=? AND seed=? AND method=?", key
                ).fetchone()
                if row is not None and not (retry_failed and row[0] == "failed"):
                    continue
                lease = self._db.execute(
                    "SELECT owner, host, pid, expires FROM leases "
                    "WHERE config_hash=? AND seed=? AND method=?", key
                ).fetchone()
                if lease is not None and lease[0] != owner and _alive(lease, now):
                    continue
                self._db.execute(
                    "INSERT OR REPLACE INTO leases VALUES (?, ?, ?, ?, ?, ?, ?)",
                    (*key, owner, _HOST, os.getpid(), now + timeout),
                )
                got.append(k)
        return got

    def release(self, owner: str) -> None:
        """Drop every lease of ``owner`` (its runs become claimable again)."""
        with self._tx():
            self._db.execute("DELETE FROM leases WHERE owner=?", (owner,))

    def leased(self, keys: Iterable[RunKey], owner: str) -> list[tuple[RunKey, str]]:
        """Of ``keys``, those under a live lease of another owner, with ``host:pid``."""
        now = time.time()
        out = []
        for k in keys:
            lease = self._db.execute(
                "SELECT owner, host, pid, expires FROM leases "
                "WHERE config_hash=? AND seed=? AND method=?", (k[0], int(k[1]), k[2])
            ).fetchone()
            if lease is not None and lease[0] != owner and _alive(lease, now):
                out.append((k, f"{lease[1]}:{lease[2]}"))
        return out

    # ------------------------------------------------------------ reading

    def statuses(self) -> dict[RunKey, str]:
        """Status of every stored run."""
        cur = self._db.execute("SELECT config_hash, seed, method, status FROM runs")
        return {(h, s, m): st for h, s, m, st in cur}

    def get(self, key: RunKey) -> dict[str, Any] | None:
        """One stored run as a dict (JSON columns decoded), or None."""
        cur = self._db.execute(
            f"SELECT {', '.join(_COLS)} FROM runs WHERE config_hash=? AND seed=? AND method=?",
            (key[0], int(key[1]), key[2]),
        )
        row = cur.fetchone()
        return None if row is None else _decode(row)

    def records(self, keys: Iterable[RunKey] | None = None) -> list[dict[str, Any]]:
        """Stored runs (all of them, or those of ``keys`` that exist, in that order)."""
        if keys is None:
            cur = self._db.execute(
                f"SELECT {', '.join(_COLS)} FROM runs ORDER BY config_hash, method, seed"
            )
            return [_decode(r) for r in cur]
        out = []
        for k in keys:
            rec = self.get(k)
            if rec is not None:
                out.append(rec)
        return out

    def scenario(self, config_hash: str) -> dict[str, Any] | None:
        """The resolved scenario recorded for ``config_hash`` (seed/methods as first stored)."""
        row = self._db.execute(
            "SELECT scenario FROM configs WHERE config_hash=?", (config_hash,)
        ).fetchone()
        return None if row is None else dict(json.loads(row[0]))

    def __len__(self) -> int:
        return int(self._db.execute("SELECT COUNT(*) FROM runs").fetchone()[0])

    def __iter__(self) -> Iterator[dict[str, Any]]:
        return iter(self.records())


def _dumps(x: Any) -> str | None:
    return None if x is None else json.dumps(x, sort_keys=True, default=_plain)


def _plain(x: Any) -> Any:
    if hasattr(x, "item"):
        return x.item()
    if hasattr(x, "tolist"):
        return x.tolist()
    return str(x)


def _decode(row: tuple[Any, ...]) -> dict[str, Any]:
    rec = dict(zip(_COLS, row, strict=True))
    for c in _JSON_COLS:
        if rec[c] is not None:
            rec[c] = json.loads(rec[c])
    return rec
