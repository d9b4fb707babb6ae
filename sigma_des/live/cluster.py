"""Live physics hosts on a Dask cluster (``sigma-des live --scheduler tcp://HOST:PORT``).

Each scenario host is a Dask **actor** (:class:`HostActor`) created on the worker its
:class:`~sigma_des.live.placement.Pin` names (``workers=[address]``, no other worker
allowed) or on any worker with the pin's ``resources``; the scheduler places it and
keeps it for the whole run. The actor starts the same ``python -m sigma_des.live.host``
process a local run starts, as a child of the worker (in a session of its own, dying
with the worker: ``PR_SET_PDEATHSIG``), in a private folder under the worker's local
directory. A process rather than a thread of the worker: the host's loop and paho's
thread then do not share the worker's GIL with its heartbeats and comms, a host that
dies does not take the worker with it, it can be killed for sure on Ctrl-C, and its
CPU is its own. The actor answers ``poll``, ``rows`` (the file the host wrote, as
bytes: there is no shared file system), ``kill`` and ``stop``.

:class:`DaskHosts` is the runner's :class:`~sigma_des.live.procs.HostGroup` of those
actors. A worker that dies takes its hosts along (their nodes crash, as a killed host
process on one machine); an actor that no longer answers within :data:`CALL_S` is
counted lost. :class:`ClockedServer` is the alignment server correcting every state's
times from its host's clock to its own (:mod:`sigma_des.live.clocksync`).
"""

from __future__ import annotations

import math
import os
import shutil
import socket
import struct
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.errors import ConfigError
from sigma_des.live.broker import reap
from sigma_des.live.clocksync import ClockBook
from sigma_des.live.cpu import CpuMeter, wake_columns
from sigma_des.live.placement import Pin, Worker
from sigma_des.live.procs import log_tail, rows_file, spawn_host
from sigma_des.live.server import LiveServer

__all__ = ["ClockedServer", "DaskHosts", "HostActor", "RemoteCpuMeter", "check_reachable",
           "connect", "correct_rows", "parse_scheduler", "workers_of"]

#: Bound on one call to a host's actor (s): longer, and the host counts as lost.
CALL_S = 5.0
#: Bound on creating the actors and starting their processes (s).
START_S = 60.0


def parse_scheduler(text: str) -> tuple[str, int]:
    """``tcp://HOST:PORT`` (or ``tls://``, or bare ``HOST:PORT``) -> (host, port).

    Raises:
        ConfigError: naming ``--scheduler``.
    """
    rest = text.split("://", 1)[1] if "://" in text else text
    host, sep, port = rest.rpartition(":")
    if (not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535
            or ("://" in text and not text.startswith(("tcp://", "tls://")))):
        raise ConfigError("--scheduler", f"must be tcp://HOST:PORT (or tls://) with a port in "
                          f"1..65535, got {text!r}")
    return host.strip("[]"), int(port)


def probe(address: str, timeout: float = 5.0) -> None:
    """Check that a plain-TCP ``address`` speaks Dask before Dask's handshake runs.

    A Dask scheduler sends its handshake as soon as it accepts a connection: a length
    (8 bytes, little-endian) and a frame count (8 bytes). A listener that stays silent
    (Dask would wait for it without end) or answers otherwise (an HTTP server, whose
    reply Dask would read as a length of exabytes) is refused here. ``tls://`` is not
    probed (TLS waits for the client to speak first).

    Raises:
        ConfigError: naming ``--scheduler`` and what answered.
    """
    if address.startswith("tls://"):
        return
    host, port = parse_scheduler(address)
    head = b""
    try:
        with socket.create_connection((host, port), timeout=timeout) as s:
            s.settimeout(timeout)
            while len(head) < 16:
                chunk = s.recv(16 - len(head))
                if not chunk:
                    break
                head += chunk
    except TimeoutError:
        pass
    except OSError as e:
        raise ConfigError("--scheduler", f"no Dask scheduler answers at {address} "
                          f"({e.strerror or e})") from None
    size, frames = struct.unpack("<QQ", head) if len(head) == 16 else (0, 0)
    if not (0 < size < 2**20 and 0 < frames < 64):
        what = ("an HTTP server" if head.startswith(b"HTTP/") else
                f"sent nothing within {timeout:g} s" if not head else f"sent {head[:16]!r}")
        raise ConfigError("--scheduler", f"{address} is not a Dask scheduler ({what}); give "
                          "the scheduler's tcp://HOST:PORT")


def connect(address: str, timeout: float = 5.0) -> Any:
    """A ``distributed.Client`` of the scheduler at ``address`` (after :func:`probe`).

    Raises:
        ConfigError: naming ``--scheduler``: nothing answers within ``timeout`` s, or
            what answers is not a Dask scheduler.
    """
    from distributed import Client

    probe(address, timeout)
    try:
        return Client(address, timeout=f"{timeout}s")  # actors find it as the default
    except Exception as e:  # noqa: BLE001  (every failure of the handshake is the option's)
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise ConfigError("--scheduler", f"no Dask scheduler answers at {address} "
                          f"within {timeout:g} s ({why})") from None


def workers_of(client: Any) -> list[Worker]:
    """The scheduler's workers (all of them)."""
    info = client.scheduler_info(n_workers=-1)["workers"]
    return [Worker(a, str(w.get("name", a)), dict(w.get("resources") or {}))
            for a, w in info.items()]


def check_reachable(workers: list[Worker], own_broker: bool) -> None:
    """Our own broker listens on 127.0.0.1 only: every worker must then be on loopback.

    Raises:
        ConfigError: naming ``--broker`` and the first worker elsewhere.
    """
    if not own_broker:
        return
    for w in workers:
        host = w.address.split("://", 1)[-1].rpartition(":")[0].strip("[]")
        if not (host.startswith("127.") or host in ("localhost", "::1")):
            raise ConfigError("--broker", f"worker {w.name} ({w.address}) is on another "
                              "machine, and the broker this command starts listens on "
                              "127.0.0.1 only; run Mosquitto where every machine reaches it "
                              "and pass --broker HOST:PORT (docs/howto/live.md)")


class HostActor:
    """One live host on a Dask worker (a Dask actor): its process, folder and rows.

    Args:
        h: the host index.
    """

    def __init__(self, h: int) -> None:
        from distributed import get_worker

        from sigma_des.version import __version__

        w = get_worker()
        self.h = h
        self.d = Path(tempfile.mkdtemp(prefix=f"sigma-des-host{h}-", dir=w.local_directory))
        self.proc: Any = None
        self.info = {"host": h, "worker": w.address, "name": str(w.name),
                     "machine": socket.gethostname(), "pid": -1, "version": __version__}

    def start(self, cfg: dict[str, Any]) -> dict[str, Any]:
        """Start the host process from ``cfg``; where it runs."""
        cfg = {**cfg, "rows_path": str(rows_file(self.d, "{run}", self.h))}
        self.proc = spawn_host(cfg, self.d, self.h)
        self.info["pid"] = self.proc.pid
        return dict(self.info)

    def poll(self) -> tuple[int | None, str]:
        """The process's exit status (None: running) and its log's tail once it exited."""
        code = self.proc.poll()
        return code, "" if code is None else log_tail(self.d, self.h)

    def rows(self, run: str, timeout: float) -> bytes | None:
        """The rows file of ``run`` (waiting up to ``timeout`` s for it), None if absent."""
        p = rows_file(self.d, run, self.h)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not p.exists():
            time.sleep(0.01)
        return p.read_bytes() if p.exists() else None

    def kill(self) -> None:
        """SIGKILL the host process (fault injection)."""
        self.proc.kill()

    def cpu(self) -> float:
        """CPU seconds (user + system, all threads) of the host process so far (NaN: gone)."""
        import psutil

        try:
            t = psutil.Process(self.proc.pid).cpu_times()
        except psutil.Error:
            return math.nan
        return float(t.user + t.system)

    def stop(self) -> int | None:
        """Terminate (then kill) the process, remove the folder; the exit status."""
        if self.proc is not None:
            reap(self.proc)
        shutil.rmtree(self.d, ignore_errors=True)
        return None if self.proc is None else self.proc.returncode


class DaskHosts:
    """The run's hosts as :class:`HostActor` s on a Dask cluster.

    Args:
        client: a connected ``distributed.Client``.
        pins: where each host may run.
        token: makes the actors' keys unique to this run.
    """

    own_clocks = True

    def __init__(self, client: Any, pins: list[Pin], token: str) -> None:
        self.client = client
        self.pins = pins
        self.token = token
        self.futures: list[Any] = []
        self.actors: list[Any] = []
        self.info: list[dict[str, Any]] = []
        self.lost: set[int] = set()
        self.codes: dict[int, int] = {}
        self._seen: tuple[float, dict[int, Any]] = (0.0, {})  # when, statuses: last poll

    def start(self, cfgs: list[dict[str, Any]]) -> None:
        """Create every actor on its worker, then start every host process."""
        from sigma_des.version import __version__

        for h, pin in enumerate(self.pins):
            kw: dict[str, Any] = ({"workers": [pin.worker], "allow_other_workers": False}
                                  if pin.worker else {"resources": pin.resources})
            self.futures.append(self.client.submit(HostActor, h, actor=True, pure=False,
                                                   key=f"sigma-des-host{h}-{self.token}", **kw))
        deadline = time.monotonic() + START_S
        for h, f in enumerate(self.futures):
            try:
                self.actors.append(f.result(timeout=max(0.1, deadline - time.monotonic())))
            except TimeoutError:
                raise RuntimeError(f"live host {h}: no Dask worker took it within {START_S:g} "
                                   f"s (pinned to {self.pins[h]})") from None
        calls = [a.start(cfg) for a, cfg in zip(self.actors, cfgs, strict=True)]
        self.info = [c.result(timeout=START_S) for c in calls]
        for i in self.info:
            if i["version"] != __version__:
                raise ConfigError("--scheduler", f"worker {i['name']} has sigma_des "
                                  f"{i['version']}, this process {__version__}: install the "
                                  "same version on every machine")

    def _call(self, h: int, method: str, *args: Any) -> Any:
        """Call ``method`` of host ``h``'s actor (a future), None once its worker is lost."""
        if h in self.lost:
            return None
        try:
            return getattr(self.actors[h], method)(*args)
        except Exception:  # Dask: "Worker holding Actor was lost"
            self.lost.add(h)
            return None

    def _poll(self, fresh: bool = False) -> dict[int, Any]:
        """Every host's status (exit code or None), lost hosts marked; cached 0.5 s."""
        when, seen = self._seen
        if not fresh and time.monotonic() - when < 0.5:
            return seen
        calls = {h: self._call(h, "poll") for h in range(len(self.actors))}
        out: dict[int, Any] = {}
        for h, c in calls.items():
            if c is None:
                continue
            try:
                out[h] = c.result(timeout=CALL_S)
            except Exception:  # the worker is gone (or does not answer): its host too
                self.lost.add(h)
        self._seen = (time.monotonic(), out)
        return out

    def alive(self) -> list[int]:
        """Hosts whose process runs on a live worker."""
        return sorted(h for h, (code, _log) in self._poll(fresh=True).items() if code is None)

    def killed(self) -> list[int]:
        """Hosts killed (SIGKILL) or lost with their worker."""
        self._poll()
        return sorted(self.lost | {h for h, (code, _l) in self._seen[1].items() if code == -9})

    def exited(self) -> tuple[int, str] | None:
        """A host that exited on its own, with its log tail."""
        for h, (code, log) in self._poll().items():
            if code is not None and code != -9:
                return h, f"status {code} on worker {self.info[h]['name']}:\n{log}"
        return None

    def kill(self, h: int) -> None:
        """SIGKILL host ``h``'s process (its worker stays)."""
        c = self._call(h, "kill")
        if c is not None:
            c.result(timeout=CALL_S)

    def meter(self, procs: dict[str, int]) -> CpuMeter:
        """A meter of ``procs`` (this machine) that also asks every host's actor for its
        process's CPU at each mark."""
        return RemoteCpuMeter(procs, self)

    def rows(self, run: str, h: int, dest: Path, deadline: float) -> bool:
        """Fetch host ``h``'s rows of ``run`` from its actor into ``dest``."""
        wait = max(0.0, deadline - time.monotonic())
        c = self._call(h, "rows", run, wait)
        if c is None:
            return False
        try:
            data = c.result(timeout=wait + CALL_S)
        except Exception:
            self.lost.add(h)
            return False
        if data is None:
            return False
        tmp = dest.with_suffix(".part")
        tmp.write_bytes(data)
        os.replace(tmp, dest)
        return True

    def where(self) -> list[dict[str, Any]]:
        """Each host's worker (address, name), machine and process id."""
        return [{k: v for k, v in i.items() if k != "version"} for i in self.info]

    def stop(self) -> None:
        """Stop every host process and release the actors (bounded: ~``2 CALL_S``)."""
        calls = [self._call(h, "stop") for h in range(len(self.actors))]
        for c in calls:
            if c is None:
                continue
            try:
                c.result(timeout=2 * CALL_S)
            except Exception:
                pass
        if self.futures:
            try:
                self.client.cancel(self.futures)
            except Exception:
                pass
        self.actors, self.futures = [], []


class RemoteCpuMeter(CpuMeter):
    """A :class:`~sigma_des.live.cpu.CpuMeter` whose marks also read each host's CPU on its
    worker (calls that do not wait: the answers are collected in :meth:`rows`; a mark
    of the metrics window runs on the server's loop). A host on this machine (loopback
    workers) counts as ours, not as background.

    Args:
        procs: this machine's processes (name -> pid).
        hosts: the run's hosts on the cluster.
    """

    def __init__(self, procs: dict[str, int], hosts: DaskHosts) -> None:
        super().__init__(procs)
        self.hosts = hosts
        self.remote: dict[str, dict[int, Any]] = {}

    def mark(self, label: str) -> None:
        """This machine's CPU now, and a request for every host's."""
        super().mark(label)
        self.remote[label] = {h: self.hosts._call(h, "cpu") for h in range(len(self.hosts.info))}

    def helper(self) -> None:
        """No helper process: the window's mark runs on the server's loop."""

    def mark_ahead(self, label: str, t0: float, when: float, loop: Any) -> None:
        """The mark on the server's ``loop`` at ``when``: it also asks every worker for
        its host's CPU, which a helper process cannot."""
        loop.call_at(when, self.mark, label)

    def _host_cpu(self, label: str, h: int) -> float:
        c = self.remote.get(label, {}).get(h)
        try:
            return float(c.result(timeout=CALL_S)) if c is not None else math.nan
        except Exception:
            return math.nan

    def rows(self, messages: dict[str, int],
             wakes: dict[str, dict[str, Any]] | None = None) -> list[dict[str, Any]]:
        """This machine's rows with a row per host (as a local run has) before the broker's."""
        base = super().rows(messages, wakes)
        here = socket.gethostname()
        out = base[:1]
        local = [0.0, 0.0]
        for h, info in enumerate(self.hosts.info):
            idle = self._host_cpu("idle1", h) - self._host_cpu("idle0", h)
            win = self._host_cpu("w1", h) - self._host_cpu("w0", h)
            out.append({"process": f"host{h}", "pid": info["pid"], "idle_s": base[0]["idle_s"],
                        "idle_cpu_s": idle, "window_s": base[0]["window_s"], "cpu_s": win,
                        "messages": messages.get(f"host{h}", math.nan),
                        **wake_columns(wakes, f"host{h}")})
            if info["machine"] == here:
                local = [local[0] + (idle if math.isfinite(idle) else 0.0),
                         local[1] + (win if math.isfinite(win) else 0.0)]
        bg = dict(base[-1])
        bg["idle_cpu_s"] = max(bg["idle_cpu_s"] - local[0], 0.0)
        bg["cpu_s"] = max(bg["cpu_s"] - local[1], 0.0)
        return out + base[1:-1] + [bg]


class ClockedServer(LiveServer):
    """The alignment server of a run whose hosts have clocks of their own: each state's
    generation and send times go from its host's clock to the server's
    (:class:`~sigma_des.live.clocksync.ClockBook`) before the rules see them; a send time
    after the receipt is counted there (and kept)."""

    book: ClockBook

    def _state(self, t: float, kind: int, node: int, frame: int, index: int, t_gen: float,
               t_send: float, hl: float, hc: int, obs: NDArray[np.float64]) -> None:
        h = self.host_of[node]
        t_gen = self.book.to_server(h, t_gen)
        t_send = self.book.latency(h, t_send, t)
        super()._state(t, kind, node, frame, index, t_gen, t_send, hl, hc, obs)


#: Columns of a host's message row (after kind) holding times on the host's clock.
_HOST_TIMES = {"trigger": (4,), "command": (4,), "state_pub": (3, 5)}


def correct_rows(kinds: NDArray[Any], values: NDArray[np.float64], h: int,
                 book: ClockBook) -> NDArray[np.float64]:
    """Host ``h``'s message rows with their host-clock times on the server's clock (the
    fit of every exchange of the run); a trigger or command received before it was
    sent after that is counted as a negative latency."""
    v = values.copy()
    for kind, cols in _HOST_TIMES.items():
        rows = kinds == kind
        for c in cols:
            v[rows, c] = book.final(h, v[rows, c])
        if kind != "state_pub":
            book.negative[h] += int((v[rows, 4] < v[rows, 3]).sum())
    return v
