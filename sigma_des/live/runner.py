"""Run a scenario live, one method after another, and return ``compare``'s Results.

Per method: a fresh run token (its own topics), the alignment server in this
process, one ``python -m sigma_des.live.host`` process per scenario host, a
``go`` with the shared time origin once every host is subscribed, ``duration``
seconds of real time, ``stop``, the hosts' counters, and the per-message rows of
every process merged into one timestamp table (``messages.csv.gz``). The broker
is our own Mosquitto (started once for all methods) unless ``broker`` names one.
Every child process and the broker are stopped on the way out, also on errors and
Ctrl-C (then the partial results of the interrupted method are kept).

Signals: SIGINT, SIGTERM and SIGHUP stop the run the same way (the first one;
later ones are noted and ignored while the bounded clean-up runs, so a second
Ctrl-C loses nothing). The methods that finished are always kept, whenever the
signal comes; only if none finished does :class:`KeyboardInterrupt` reach the
caller. A :class:`~sigma_des.live.broker.Janitor` removes the temporary folders
(host configs and logs, the broker's password file) even if we are SIGKILLed.
"""

from __future__ import annotations

import gc
import os
import secrets
import sys
import tempfile
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import pandas as pd

from sigma_des.api import Results
from sigma_des.config import Scenario, to_dict
from sigma_des.errors import ConfigError
from sigma_des.live.broker import Broker, BrokerAddress, Janitor, parse_broker, wait_port
from sigma_des.live.clocksync import ClockBook, SyncClient, SyncTopics
from sigma_des.live.cpu import CpuMeter, message_counts, wake_sums
from sigma_des.live.interrupts import Interrupts
from sigma_des.live.limits import check_live, check_size
from sigma_des.live.loop import Client
from sigma_des.live.lost import hop_notes, lost_notes
from sigma_des.live.procs import HostGroup, LocalHosts, rows_file
from sigma_des.live.results import (
    LIVE_METRICS,
    MESSAGE_COLUMNS,
    host_fidelity,
    live_info,
    message_table,
)
from sigma_des.live.server import LiveServer
from sigma_des.live.wire import STATE_BYTES, TRIGGER_BYTES, Topics, run_token
from sigma_des.metrics.reports import MethodReport

__all__ = ["LiveOptions", "MESSAGE_COLUMNS", "run_live"]

#: Longest wait (s) of one step of the server's loop before the run.
PUMP_STEP = 0.02
#: How long (s) before the time origin the idle window ends and the run's loop starts
#: (it then waits for trigger 0 itself).
START_LEAD = 0.02


@dataclass(frozen=True)
class LiveOptions:
    """Live-only settings (not part of the scenario).

    Attributes:
        broker: ``HOST:PORT`` of a running broker; None: start our own Mosquitto.
        username: MQTT user for an external broker.
        password: MQTT password for an external broker.
        tls_ca: PEM text of the CA of an external broker's TLS certificate ('' : no TLS).
        broker_port: port for our own broker (None: a free one).
        impair: apply the scenario's link latency/loss in the clients.
        step_delay: add the scenario's drawn ``compute.step_time`` to each node's real step.
        max_inflight: QoS 1 in-flight window per client (0: unlimited).
        bundle: a host sends the states its nodes finish in one loop turn as one PUBLISH.
        kill_broker_at: fault injection: kill our broker at this time (s) ...
        broker_down_s: ... and start it again this long after.
        kill_host_at: fault injection: ``(host, t)``: kill that host process at ``t``.
        ready_timeout: seconds to wait for the host processes to subscribe.
        idle_window: seconds between ``go`` and the first trigger (>= 0.3), the idle
            window whose CPU rates ``calibrate`` takes as each process's idle loop cost.
        record: keep what ``live --record`` writes (states' poses, snapshots, renders).
        hook: called as ``hook(addr, topics, server)`` right after the first trigger is
            scheduled (tests use it to start a rogue client).
        force: run even if :func:`check_size` refuses (too many host processes for the
            CPU cores, or more memory than is available).
        scheduler: address of a Dask scheduler (``tcp://HOST:PORT``): each host runs on
            one of its workers (:mod:`sigma_des.live.cluster`), the clocks are reconciled
            (:mod:`sigma_des.live.clocksync`); None: host processes on this machine.
        placement: with ``scheduler``: ``spread``, ``pack`` or a placement TOML file
            (:mod:`sigma_des.live.placement`).
        sync_interval: with ``scheduler``: seconds between two clock exchanges with a host
            during the run.
    """

    broker: str | None = None
    username: str = ""
    password: str = ""
    tls_ca: str = ""
    broker_port: int | None = None
    impair: bool = True
    step_delay: bool = True
    max_inflight: int = 0
    bundle: bool = False
    kill_broker_at: float | None = None
    broker_down_s: float = 0.5
    kill_host_at: tuple[int, float] | None = None
    ready_timeout: float = 60.0
    idle_window: float = 1.0
    record: bool = False
    hook: Callable[[BrokerAddress, Topics, LiveServer], None] | None = None
    force: bool = False
    scheduler: str | None = None
    placement: str = "spread"
    sync_interval: float = 0.5

    def __post_init__(self) -> None:
        if not 0.3 <= self.idle_window <= 60.0:
            raise ConfigError("idle_window", f"must be in 0.3..60 s, got {self.idle_window}")
        if self.max_inflight < 0:
            raise ConfigError("--max-inflight", f"must be >= 0, got {self.max_inflight}")
        if self.broker is not None and self.kill_broker_at is not None:
            raise ConfigError("kill_broker_at", "needs our own broker (no --broker)")
        if self.tls_ca and self.broker is None:
            raise ConfigError("--tls-ca", "is for a broker of yours (--broker HOST:PORT)")
        if not 0.05 <= self.sync_interval <= 60.0:
            raise ConfigError("sync_interval", f"must be in 0.05..60 s, got {self.sync_interval}")


Done = Callable[[Results, pd.DataFrame], None]


def run_live(sc: Scenario, methods: list[str] | None = None,
             opts: LiveOptions | None = None,
             progress: bool = False, on_method: Done | None = None,
             ) -> tuple[Results, pd.DataFrame, dict[str, dict[str, list[Any]]]]:
    """Run ``methods`` live on ``sc``.

    Args:
        sc: the scenario.
        methods: the methods to run (None: the scenario's).
        opts: live-only settings.
        progress: print a line per method on stderr.
        on_method: called as ``on_method(results, messages)`` after each method that
            finished while more are to come (``results.interrupted`` is True then: they
            are partial), e.g. to write them at once.

    Returns:
        The Results (as ``compare``'s, ``mode = "live"``), the message table and, per
        method, what the server kept for a recording (empty unless ``opts.record``).

    Raises:
        ConfigError: unknown method, unsupported keys, a run too big for this machine
            (:func:`check_size`), mosquitto missing, broker unreachable or its port in use.
        KeyboardInterrupt: SIGINT, SIGTERM or SIGHUP before any method finished.
    """
    opts = opts or LiveOptions()
    ms = tuple(methods) if methods is not None else sc.methods
    sc = replace(sc, methods=ms)
    check_live(sc)
    check_size(sc, opts.force, remote_hosts=opts.scheduler is not None)
    res = Results(sc)
    res.mode = "live"
    tables: list[pd.DataFrame] = []
    kept: dict[str, dict[str, list[Any]]] = {}
    with Interrupts() as sig, Janitor() as janitor:
        try:
            _run_all(sc, ms, opts, progress, on_method, sig, janitor, res, tables, kept)
        except KeyboardInterrupt:
            if not res.methods:
                raise
            res.interrupted = True
    return res, _concat(tables), kept


def _concat(tables: list[pd.DataFrame]) -> pd.DataFrame:
    return pd.concat(tables, ignore_index=True) if tables else pd.DataFrame(
        columns=list(MESSAGE_COLUMNS))


def _run_all(sc: Scenario, ms: tuple[str, ...], opts: LiveOptions, progress: bool,
             on_method: Done | None, sig: Interrupts, janitor: Janitor, res: Results,
             tables: list[pd.DataFrame], kept: dict[str, dict[str, list[Any]]]) -> None:
    """The methods one after another on one broker and one set of host processes."""
    with ExitStack() as stack:
        broker: Broker | None = None
        if opts.broker is None:
            broker = Broker(port=opts.broker_port, max_inflight=opts.max_inflight,
                            janitor=janitor)
            stack.callback(broker.stop)
            addr = broker.start()
        else:
            host, port = parse_broker(opts.broker)
            if not wait_port(host, port, 2.0):
                raise ConfigError("--broker", f"nothing accepts connections at {host}:{port}")
            addr = BrokerAddress(host, port, opts.username, opts.password, opts.tls_ca)
        keep = os.environ.get("SIGMA_DES_LIVE_KEEP")  # keep the hosts' logs for debugging
        if keep:
            d = Path(keep)
        else:
            d = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="sigma-des-live-")))
            janitor.watch(d)
        d.mkdir(parents=True, exist_ok=True)
        runs = [(m, run_token(m)) for m in ms]
        group = _host_group(sc, opts, d, stack)
        group.start([_host_cfg(sc, runs, addr, opts, h, group.own_clocks)
                     for h in range(sc.hosts)])
        book = ClockBook(sc.hosts) if group.own_clocks else None  # kept over the methods
        for m, run in runs:
            out, table, interrupted = _run_method(sc, m, run, addr, opts, broker, group, d,
                                                  progress, book)
            kept[m] = out.pop("kept")
            res.add(m, MethodReport.of(out, {"requested": "live", "used": "live",
                                             "fallback": ""}))
            res.live[m] = out["live"]
            tables.append(table)
            if interrupted:
                res.interrupted = True
                break
            if on_method is not None and len(res.methods) < len(ms):
                res.interrupted = True  # partial until the last method is in
                with sig.held():
                    on_method(res, _concat(tables))
                res.interrupted = False


def _host_group(sc: Scenario, opts: LiveOptions, d: Path, stack: ExitStack) -> HostGroup:
    """The host processes: here, or (``opts.scheduler``) on the Dask cluster's workers."""
    if opts.scheduler is None:
        local = LocalHosts(d)
        stack.callback(local.stop)
        return local
    from sigma_des.live.cluster import DaskHosts, check_reachable, connect, workers_of
    from sigma_des.live.placement import assign, read_placement

    client = connect(opts.scheduler)
    stack.callback(client.close, 5)
    workers = workers_of(client)
    check_reachable(workers, opts.broker is None)
    pins = assign(sc.hosts, workers, read_placement(opts.placement), opts.placement)
    hosts = DaskHosts(client, pins, secrets.token_hex(4))
    stack.callback(hosts.stop)
    return hosts


def _host_cfg(sc: Scenario, runs: list[tuple[str, str]], addr: BrokerAddress,
              opts: LiveOptions, h: int, sync: bool) -> dict[str, Any]:
    """Host ``h``'s config: it serves every run (method) in turn."""
    return {
        "scenario": to_dict(sc),
        "runs": runs,
        "host": h,
        "broker": addr.__dict__,
        "qos": sc.net.qos,
        "impair": opts.impair,
        "step_delay": opts.step_delay,
        "max_inflight": opts.max_inflight,
        "bundle": opts.bundle,
        "sync": sync,
    }


def _pump(srv: LiveServer, seconds: float) -> None:
    srv.loop.stopped = False
    srv.loop.run(until=srv.loop.now + seconds)


def _idle_until(srv: LiveServer, t: float) -> None:
    """Handle the server's messages until ``t`` (monotonic seconds), in steps of at most
    :data:`PUMP_STEP` and never past ``t``: a step past the time origin would issue
    trigger 0 late, and Lock-Step, whose grid restarts at a late barrier, would run the
    whole run on a shifted grid (a phase to the ticks the DES never has)."""
    while (left := t - time.monotonic()) > 0:
        _pump(srv, min(PUMP_STEP, left))


def _wait_ready(srv: LiveServer, group: HostGroup, expected: int, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while len(srv.ready) < expected:
        bad = group.exited()
        if bad is not None:
            raise RuntimeError(f"live host {bad[0]} exited at start ({bad[1]})")
        if time.monotonic() > deadline:
            raise RuntimeError(f"live hosts not ready after {timeout} s: {sorted(srv.ready)}")
        _pump(srv, 0.05)


def _run_method(sc: Scenario, m: str, run: str, addr: BrokerAddress, opts: LiveOptions,
                broker: Broker | None, group: HostGroup, d: Path, progress: bool,
                book: ClockBook | None) -> tuple[dict[str, Any], pd.DataFrame, bool]:
    topics = Topics(run)
    interrupted = False
    with ExitStack() as stack:
        def factory(subs: list[tuple[str, int]], cb: Any) -> Client:
            return Client(addr, f"{run}-srv", subs, cb, opts.max_inflight)

        srv = _server(sc, m, factory, topics, opts, book)
        try:
            srv.client.start(timeout=5.0)
        except ConnectionError as e:
            raise ConfigError("--broker", str(e)) from None
        stack.callback(srv.client.stop)
        srv.warm_up()
        gc.collect()  # what earlier runs left, before the clock matters (the loop pauses it)
        live = group.alive()
        _wait_ready(srv, group, len(live), opts.ready_timeout)
        meter = _cpu_meter(group, broker)
        meter.helper()  # the window's mark-taker, started before the idle window
        stack.callback(meter.close)
        t0 = _go(srv, opts, addr, run, live, book, stack)
        meter.mark("idle0")
        _idle_until(srv, t0 - START_LEAD)
        meter.mark("idle1")
        meter.mark_ahead("w0", t0, sc.warmup, srv.loop)  # not on the loop: it would stall it
        _inject(srv, opts, broker, group)
        if progress:
            print(f"sigma-des live: {m}: {len(live)} hosts ready, running {sc.duration:g} s",
                  file=sys.stderr, flush=True)
        # the loop starts before t0 and waits for trigger 0 itself (at t0, not late)
        w0 = time.perf_counter() + max(0.0, t0 - time.monotonic())
        srv.start(t0)
        if opts.hook is not None:
            opts.hook(addr, topics, srv)
        try:
            srv.loop.run(until=sc.duration)
        except KeyboardInterrupt:
            interrupted = True
        meter.mark("w1")
        cpu_notes = meter.collect()
        srv.wall_seconds = time.perf_counter() - w0
        srv.running = False
        srv.stats.clear()  # counters sent before stop are not the hosts' (forged)
        broker_down = srv.client.disconnects >= srv.client.connects  # and never came back
        srv.client.publish(topics.ctl, b"stop", 1)
        alive = group.alive()
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and not set(alive) <= set(srv.stats):
            _pump(srv, 0.05)
        for h in alive:  # the rows file follows the stats message
            group.rows(run, h, rows_file(d, run, h), deadline)
        out = srv.finish()
        table = message_table(run, m, srv, d, sc.hosts, book)
        if sc.fidelity.enabled:
            host_fidelity(out, sc, srv, d, run)
    out["kept"] = srv.kept
    out["live"] = live_info(srv, group, table, sc)
    out["live"]["warnings"] = lost_notes(out["live"], sc.hosts, broker_down) + (
        hop_notes(table, sc, opts.impair) if opts.broker is not None else []) + cpu_notes
    if book is not None:
        out["live"]["clock"] = book.report(sc.duration)
    out["live"]["cpu"] = meter.rows(message_counts(srv.ledger.as_dict(), srv.stats, sc.net.qos),
                                    wake_sums(srv.loop.wake.as_dict(), srv.stats))
    # what `calibrate` writes into the scenario: the machine's CPUs, the bundling, the
    # load, the records' sizes on this version's wire
    out["live"].update(cores=len(os.sched_getaffinity(0)), bundle=opts.bundle,
                       load1=os.getloadavg()[0], state_bytes=STATE_BYTES,
                       trigger_bytes=TRIGGER_BYTES)
    out["metrics"].update({k: out["live"][k] for k in LIVE_METRICS})
    return out, table, interrupted


def _server(sc: Scenario, m: str, factory: Any, topics: Topics, opts: LiveOptions,
            book: ClockBook | None) -> LiveServer:
    """The alignment server; with hosts on clocks of their own (``book``), one that
    corrects their times."""
    if book is None:
        return LiveServer(sc, m, factory, topics, sc.net.qos, opts.impair, opts.record,
                          opts.bundle)
    from sigma_des.live.cluster import ClockedServer

    srv = ClockedServer(sc, m, factory, topics, sc.net.qos, opts.impair, opts.record,
                        opts.bundle)
    srv.book = book
    book.new_method()
    return srv


def _go(srv: LiveServer, opts: LiveOptions, addr: BrokerAddress, run: str, live: list[int],
        book: ClockBook | None, stack: ExitStack) -> float:
    """Publish ``go`` with the time origin ``t0`` (returned, this machine's clock) one
    idle window ahead: on the shared clock, or (hosts on clocks of their own) each host's
    origin on its clock after a burst of clock exchanges, which go on during the run."""
    if book is None:
        t0 = time.monotonic() + opts.idle_window
        srv.client.publish(srv.topics.ctl, f"go:{t0!r}".encode(), 1)
        return t0
    sync = SyncClient(addr, run, book, opts.max_inflight)
    sync.start()
    stack.callback(sync.stop)
    sync.burst(rounds=8, gap=0.02, timeout=5.0, hosts=live)
    t0 = time.monotonic() + opts.idle_window
    for h, t0_h in book.start(t0, live).items():
        srv.client.publish(SyncTopics(run).go(h), f"go:{t0_h!r}".encode(), 1)
    sync.periodic(opts.sync_interval)
    return t0


def _cpu_meter(group: HostGroup, broker: Broker | None) -> CpuMeter:
    """CPU meter of this process (the server), the hosts and our broker."""
    procs = {"server": os.getpid()}
    if broker is not None and broker.proc is not None:
        procs["broker"] = broker.proc.pid
    return group.meter(procs)


def _inject(srv: LiveServer, opts: LiveOptions, broker: Broker | None,
            group: HostGroup) -> None:
    if opts.kill_broker_at is not None and broker is not None:
        srv.loop.call_at(opts.kill_broker_at, broker.kill)
        srv.loop.call_at(opts.kill_broker_at + opts.broker_down_s, broker.restart)
    if opts.kill_host_at is not None:
        h, t = opts.kill_host_at
        srv.loop.call_at(t, group.kill, h)
