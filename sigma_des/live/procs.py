"""Where the physics host processes of a live run live: this machine, or a Dask cluster.

A :class:`HostGroup` starts one host process per scenario host from its config (the
JSON that ``python -m sigma_des.live.host`` reads), says which are alive, fetches the
rows each wrote for a run, kills one (fault injection) and stops them all (bounded).
:class:`LocalHosts` runs them as child processes here, as ``sigma-des live`` always
has; :class:`~sigma_des.live.cluster.DaskHosts` runs each on a Dask worker.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Protocol

from sigma_des.live.broker import child_setup, reap
from sigma_des.live.cpu import CpuMeter

__all__ = ["HostGroup", "LocalHosts", "log_tail", "rows_file", "spawn_host"]


class HostGroup(Protocol):
    """The host processes of a run (one per scenario host, index = host)."""

    #: Hosts' clocks differ from the server's (clock exchanges needed).
    own_clocks: bool

    def start(self, cfgs: list[dict[str, Any]]) -> None:
        """Start host ``h`` from ``cfgs[h]`` (without its ``rows_path``: the group sets it)."""

    def alive(self) -> list[int]:
        """Hosts whose process runs."""

    def killed(self) -> list[int]:
        """Hosts whose process was killed (or whose machine was lost)."""

    def exited(self) -> tuple[int, str] | None:
        """A host that exited on its own, with its status and log tail (None: none)."""

    def kill(self, h: int) -> None:
        """Kill host ``h``'s process (fault injection)."""

    def meter(self, procs: dict[str, int]) -> CpuMeter:
        """A CPU meter of ``procs`` (this machine's: server, broker) and of the hosts."""

    def rows(self, run: str, h: int, dest: Path, deadline: float) -> bool:
        """Put host ``h``'s rows of ``run`` at ``dest`` (wait until ``deadline``,
        monotonic); False if there are none."""

    def where(self) -> list[dict[str, Any]]:
        """Where each host runs (machine, worker, pid)."""

    def stop(self) -> None:
        """Stop every host process (bounded)."""


def spawn_host(cfg: dict[str, Any], d: Path, h: int, **popen: Any) -> subprocess.Popen[bytes]:
    """Write host ``h``'s config into ``d`` and start ``python -m sigma_des.live.host`` on
    it, logging to ``d/host<h>.log``, in a session of its own that dies with its parent."""
    env = dict(os.environ)
    here = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = here + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    path = d / f"host{h}.json"
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)  # it holds the password
    with os.fdopen(fd, "w") as fh:
        fh.write(json.dumps(cfg, default=float))
    with open(d / f"host{h}.log", "wb") as log:
        return subprocess.Popen([sys.executable, "-m", "sigma_des.live.host", str(path)],
                                stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                env=env, preexec_fn=child_setup, **popen)


def rows_file(d: Path, run: str, h: int) -> Path:
    """The file in ``d`` where host ``h`` writes its rows of ``run`` (``run = "{run}"``:
    the template a host's config carries)."""
    return d / f"rows_{run}_h{h}.npz"


def log_tail(d: Path, h: int) -> str:
    """The last lines of host ``h``'s log."""
    p = d / f"host{h}.log"
    return p.read_text(errors="replace")[-800:] if p.exists() else ""


class LocalHosts:
    """Host processes on this machine (children of this process; Ctrl-C reaches only us).

    Args:
        d: the run's private folder (configs, logs, rows).
    """

    own_clocks = False

    def __init__(self, d: Path) -> None:
        self.d = d
        self.procs: list[subprocess.Popen[bytes]] = []

    def start(self, cfgs: list[dict[str, Any]]) -> None:
        """One child process per host."""
        for h, cfg in enumerate(cfgs):
            cfg = {**cfg, "rows_path": str(rows_file(self.d, "{run}", h))}
            self.procs.append(spawn_host(cfg, self.d, h))

    def alive(self) -> list[int]:
        """Hosts whose process runs."""
        return [h for h, p in enumerate(self.procs) if p.poll() is None]

    def killed(self) -> list[int]:
        """Hosts killed by SIGKILL."""
        return [h for h, p in enumerate(self.procs) if p.returncode == -9]

    def exited(self) -> tuple[int, str] | None:
        """A host that exited other than by SIGKILL, with its log tail."""
        for h, p in enumerate(self.procs):
            if p.poll() is not None and p.returncode != -9:
                return h, f"status {p.returncode}:\n{log_tail(self.d, h)}"
        return None

    def kill(self, h: int) -> None:
        """SIGKILL host ``h``."""
        self.procs[h].kill()

    def meter(self, procs: dict[str, int]) -> CpuMeter:
        """A meter of ``procs`` and every live host (the hosts before the broker)."""
        hosts = {f"host{h}": p.pid for h, p in enumerate(self.procs) if p.poll() is None}
        first = dict(list(procs.items())[:1])
        return CpuMeter({**first, **hosts, **procs})

    def rows(self, run: str, h: int, dest: Path, deadline: float) -> bool:
        """The host writes its rows into our folder: wait for the file."""
        while time.monotonic() < deadline and not dest.exists():
            time.sleep(0.01)
        return dest.exists()

    def where(self) -> list[dict[str, Any]]:
        """Every host on this machine."""
        import socket

        return [{"host": h, "machine": socket.gethostname(), "worker": "", "pid": p.pid}
                for h, p in enumerate(self.procs)]

    def stop(self) -> None:
        """Terminate every host (<= 6 s each)."""
        for p in self.procs:
            reap(p)
