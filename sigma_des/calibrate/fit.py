"""Fit the DES's network, broker, CPU and compute parameters from a live run.

From the message table (``messages.csv.gz`` or an MCAP recording) inside the metrics
window, and the run's ``cpu.csv`` and ``summary.json``:

* **the deployment** (:mod:`sigma_des.calibrate.fit_cpu`). Without a ``cpu.csv``: no
  CPU stage, the broker's per-delivery service the 5th percentile of the gaps between
  consecutive receivers of a trigger (:func:`delivery_floor`), its publish service
  the base scenario's;
* **per-hop latency per direction** (empirical sample files): states give the upward
  path, triggers (not commands, which hold the server's publish queue) the downward
  one; a hop is ``(path latency - CPU services on the path) / 2``
  (:func:`~sigma_des.calibrate.fit_cpu.path_services`), the path latency **de-queued**
  first (:mod:`sigma_des.calibrate.dequeue`). Without a CPU stage the server's receive
  cost is folded into the server link's down latency when it exceeds 5 % of the hop;
* **node step time** (:mod:`sigma_des.calibrate.fit_step`) and ``compute.host_share``;
* **wire sizes** set to the live payloads and topics, so the DES counts the same bytes.

What cannot be fitted is said, never filled in silently (``report["warnings"]``, or
refused with ``strict``). With one DES client per node (live has one per host)
:func:`for_target` scales the per-delivery service by ``hosts / nodes``. The result is
the live run's scenario with these parameters replaced, as TOML that ``sigma-des
compare`` runs. The rules and why: docs/concepts/live-and-calibration.md.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from sigma_des.calibrate.burst import floor_share
from sigma_des.calibrate.dequeue import HOLD_TOL, censored_weights, held, quantiles, sender_waits
from sigma_des.calibrate.fit_cpu import fit_deployment, live_info, path_services, recorded
from sigma_des.calibrate.fit_step import MIN_SAMPLES, fit_compute
from sigma_des.calibrate.messages import read_messages
from sigma_des.calibrate.report import calibrated_toml, report_lines
from sigma_des.config import Scenario, load, to_toml
from sigma_des.errors import ConfigError
from sigma_des.factory import make_dynamics
from sigma_des.guard import atomic_write, output_file, read_text
from sigma_des.live.wire import STATE_BYTES, TRIGGER_BYTES, command_bytes, state_topic_bytes
from sigma_des.loading import from_dict
from sigma_des.net.latency import Dist
from sigma_des.net.spec import BrokerSpec, DeploymentSpec, NetSpec

__all__ = ["MIN_SAMPLES", "STALL_FACTOR", "calibrate", "calibrated_toml", "delivery_floor",
           "fanout_slope", "for_target", "remove_files", "report_lines", "sample_files",
           "stalls"]

#: a path latency above this multiple of its 99th percentile is a process stall
STALL_FACTOR = 10.0


def _trigger_keys(trig: pd.DataFrame) -> list[str]:
    """The columns naming one trigger: its frame, within its method when there is one."""
    return ["method", "frame"] if "method" in trig.columns else ["frame"]


def fanout_slope(trig: pd.DataFrame) -> tuple[float, float]:
    """Least-squares ``(intercept, slope)`` of trigger delay vs position in its fan-out.

    Args:
        trig: rows with ``frame``, ``t_send``, ``t_recv`` (one per receiving client), and
            ``method`` if they come from several runs (each method's times start at 0,
            so a frame is one trigger only within its method).

    Returns:
        Intercept (s) and slope (s per delivery); slope 0 with fewer than two receivers.
    """
    if trig.empty:
        return 0.0, 0.0
    keys = _trigger_keys(trig)
    t = trig.sort_values([*keys, "t_recv"], kind="stable")
    pos = t.groupby(keys).cumcount().to_numpy(dtype=np.float64)
    delay = (t["t_recv"] - t["t_send"]).to_numpy()
    if pos.max() < 1:
        return float(delay.mean()), 0.0
    slope, intercept = np.polyfit(pos, delay, 1)
    return float(intercept), float(slope)


def delivery_floor(trig: pd.DataFrame, q: float = 0.05) -> float:
    """The ``q`` quantile of the gaps between consecutive receivers of one trigger (s).

    Args:
        trig: rows with ``frame`` and ``t_recv`` (one per receiving client), and
            ``method`` if they come from several runs (as :func:`fanout_slope`).
        q: the quantile.

    Returns:
        The quantile, 0 when no trigger had two receivers.
    """
    keys = _trigger_keys(trig)
    t = trig.sort_values([*keys, "t_recv"], kind="stable")
    g = t.groupby(keys, sort=False).ngroup().to_numpy()
    same = g[1:] == g[:-1]
    gaps = np.diff(t["t_recv"].to_numpy())[same]
    return float(np.quantile(gaps, q)) if gaps.size else 0.0


def apply_overrides(sc: Scenario, overrides: list[str]) -> Scenario:
    """``sc`` with ``key=value`` overrides (the ``--set`` syntax), validated."""
    import tempfile

    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as fh:
        fh.write(to_toml(sc))
        path = fh.name
    try:
        return load(path, overrides)
    finally:
        Path(path).unlink()


def _mcap_scenario(path: Path) -> dict[str, Any] | None:
    """The scenario stored in an MCAP recording's ``sigma_des`` metadata record, if any."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        for rec in make_reader(fh).iter_metadata():
            if rec.name == "sigma_des" and "scenario" in rec.metadata:
                d = json.loads(rec.metadata["scenario"])
                return d if d else None
    return None


def _summary_scenario(summ: Path) -> dict[str, Any]:
    """The ``scenario`` table of a live run's ``summary.json``.

    Raises:
        ConfigError: naming the file if it is not UTF-8 JSON or has no ``scenario`` table.
    """
    text = read_text(summ, str(summ), "summary.json")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise ConfigError(str(summ), f"not valid JSON ({e.msg} at line {e.lineno}); expected "
                          "the summary.json of a `sigma-des live --out` run") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("scenario"), dict):
        raise ConfigError(str(summ), "has no 'scenario' table; expected the summary.json of "
                          "a `sigma-des live --out` run")
    return doc["scenario"]  # type: ignore[no-any-return]


def _base_scenario(source: Path, msgs: pd.DataFrame) -> Scenario:
    if source.suffix == ".mcap":
        d = _mcap_scenario(source)
        if d is not None:
            return from_dict(Scenario, d)  # type: ignore[no-any-return]
    summ = (source if source.is_dir() else source.parent) / "summary.json"
    if summ.exists():
        return from_dict(Scenario, _summary_scenario(summ))  # type: ignore[no-any-return]
    n = int(msgs["node"].max()) + 1
    return Scenario(nodes=n, hosts=min(n, max(1, int(msgs.get("host", pd.Series([0])).max()) + 1)))


def _window(source: Path) -> tuple[Scenario, pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """The base scenario, all messages, those in its run window and the (first-sent)
    states of the window."""
    msgs = read_messages(source)
    base = _base_scenario(source, msgs)
    # an MCAP table (sigma_des.record.read_table) has the contract columns only
    if "republish" not in msgs:
        msgs = msgs.assign(republish=False)
    if "t_trig" not in msgs:
        msgs = msgs.assign(t_trig=np.nan)
    if "host" not in msgs:
        nodes = msgs["node"].fillna(0).clip(0).astype(int)
        msgs = msgs.assign(host=np.asarray(base.host_of)[nodes])
    w = msgs[(msgs["t_send"] >= base.warmup) & (msgs["t_send"] < base.duration)]
    states = w[(w["kind"] == "state") & ~w["republish"].astype(bool)]
    if len(states) < 10:
        raise ConfigError(str(source), f"only {len(states)} states in the window; need >= 10")
    return base, msgs, w, states


def stalls(x: NDArray[np.float64]) -> NDArray[np.bool_]:
    """The path latencies taken as stalls of a process, not per-message delays: above
    :data:`STALL_FACTOR` times their 99th percentile. The DES draws each hop
    independently and delivers a stream in order, so one live stall (every message of
    a moment late together) drawn as a per-message latency would recur at random and
    hold every later message of its connection behind it."""
    if x.size == 0:
        return np.zeros(0, dtype=bool)
    return np.asarray(x > STALL_FACTOR * np.percentile(x, 99), dtype=bool)


def _hop_samples(x: NDArray[np.float64], held_: NDArray[np.bool_], services: float
                 ) -> NDArray[np.float64]:
    """Per-hop draws from path latencies ``x`` (host -> broker -> receiver): the
    de-queued path latency (:mod:`sigma_des.calibrate.dequeue`) less the broker's services,
    split evenly over the two hops, stalls (:func:`stalls`) left out; one sample per
    message kept, ascending."""
    keep = ~stalls(x)
    xs, w = censored_weights(x[keep], held_[keep])
    return np.clip((quantiles(xs, w, int(keep.sum())) - services) / 2.0, 0.0, None)


def _stall_note(x: NDArray[np.float64], what: str, warn: list[str]) -> int:
    """Say how many of ``x`` were left out as stalls; their number."""
    cut = stalls(x)
    k = int(cut.sum())
    if k:
        warn.append(f"{k} of {x.size} {what} latencies above {STALL_FACTOR:g} x their 99th "
                    f"percentile (> {STALL_FACTOR * np.percentile(x, 99) * 1e3:.3g} ms, mean "
                    f"{x[cut].mean() * 1e3:.3g} ms) taken as process stalls and left out of "
                    "the hop draws (the DES has no stall model; "
                    "docs/concepts/live-and-calibration.md)")
    return k


def _paths(w: pd.DataFrame, states: pd.DataFrame, tol: float, srv_up: float,
           srv_down: float) -> dict[str, Any]:
    """Path latencies of both directions, with the in-order holds flagged.

    Up (states): one in-order stream per method into the server (the DES's server
    connection carries every state). Down (triggers): one per method and receiving
    host. Commands are left out: a tick's commands leave the server together, so
    their latencies hold the server's publish queue, which the DES adds itself (they
    take the triggers' hops). Rows of one receipt (a recording repeats a host's trigger
    per node) count once. A delivery within ``tol`` after the previous one into its
    receiver, or after the receiver's thread is free again (each delivery holds it for
    ``srv_up`` / ``srv_down``), may have waited behind it, on the stream or for the
    thread (:func:`~sigma_des.calibrate.dequeue.held`).
    """
    up_conn = pd.factorize(states["method"])[0]
    lat_up = (states["t_recv"] - states["t_send"]).to_numpy()
    down = w[w["kind"] == "trigger"].drop_duplicates(
        ["method", "kind", "frame", "host", "t_recv"])
    down = down[np.isfinite(down["t_recv"])]
    down_conn = pd.factorize(down["method"].astype(str) + "/" + down["host"].astype(str))[0]
    return {
        "up": lat_up,
        "up_held": held(up_conn, states["t_send"], states["t_recv"], tol, srv_up),
        "down": (down["t_recv"] - down["t_send"]).to_numpy(),
        "down_held": held(down_conn, down["t_send"], down["t_recv"], tol, srv_down),
    }


def _write_latency_files(d: Path, files: dict[str, NDArray[np.float64]], key: str
                         ) -> dict[str, Path]:
    """Write each sample array as ``<name>.txt`` in ``d`` (all or nothing per file:
    :func:`~sigma_des.guard.atomic_write`); their paths by name. ``key`` is named in
    an error."""
    out: dict[str, Path] = {}
    try:
        for name, samples in files.items():
            out[name] = output_file(d / f"{name}.txt", key)
            atomic_write(out[name], partial(np.savetxt, X=samples, fmt="%.9g"), key)
    except ConfigError:  # the set, all or none: a later file failed, the earlier go too
        remove_files(out.values())
        raise
    return out


def remove_files(paths: Iterable[Path]) -> None:
    """Remove the files a failed calibration wrote (a set is written all or none)."""
    for p in paths:
        p.unlink(missing_ok=True)


def sample_files(sc: Scenario) -> list[Path]:
    """The latency sample files the calibrated scenario ``sc`` reads (its empirical
    link latencies), each once."""
    links = (sc.net.host_link, sc.net.server_link)
    dists = [d for ln in links for d in (ln.latency, ln.latency_down) if d is not None]
    return list(dict.fromkeys(Path(d.file) for d in dists if d.dist == "empirical"))


def _fit_links(base: Scenario, w: pd.DataFrame, states: pd.DataFrame,
               cpu: dict[str, float], d: Path, tol: float, fold_ok: bool, warn: list[str],
               key: str = "--out") -> tuple[NetSpec, dict[str, Any]]:
    """Per-direction de-queued hop latencies (and, without a CPU stage, the server's
    receive queue) as the links' empirical latency files (see the module doc).

    ``cpu`` is :func:`~sigma_des.calibrate.fit_cpu.path_services`: the CPU services the DES
    adds on each path (taken out of every sample). A delivery within ``tol`` of its
    receiver's thread being busy (each receipt holds it ``recv_up``/``recv_down``) may
    have waited (on the stream or for the thread): censored. ``tol = 0`` keeps the
    measured latencies."""
    up_srv = cpu.get("recv_up", 0.0) if tol > 0 else 0.0
    down_srv = cpu.get("recv_down", 0.0) if tol > 0 else 0.0
    p = _paths(w, states, tol, up_srv, down_srv)
    # a state left its host when the host's thread was next idle (the DES adds that)
    wait_up = sender_waits(states["method"].astype(str) + "/" + states["host"].astype(str),
                           states["t_send"], cpu.get("send_up", 0.0), tol)
    p["up"] = p["up"] - wait_up
    if p["up"].size < MIN_SAMPLES:
        warn.append(f"only {p['up'].size} state latencies in the window (< {MIN_SAMPLES})")
    hop_up = _hop_samples(p["up"], p["up_held"], cpu["up"])
    stalls_up = _stall_note(p["up"], "state", warn)
    queue = np.nan_to_num(np.clip((states["t_trig"] - states["t_recv"]).to_numpy(), 0.0, None))
    fold = fold_ok and float(queue.mean()) > 0.05 * float(hop_up.mean())
    files = {"hop_up": hop_up}
    if fold:  # no CPU stage: the server link's down hop carries the server's receive queue
        files["server_down"] = _hop_samples(p["up"] + 2.0 * queue, p["up_held"], cpu["up"])
    stalls_down = 0
    if p["down"].size >= MIN_SAMPLES:
        files["hop_down"] = _hop_samples(p["down"], p["down_held"], cpu["down"])
        stalls_down = _stall_note(p["down"], "trigger", warn)
    else:
        warn.append(f"only {p['down'].size} trigger latencies in the window "
                    f"(< {MIN_SAMPLES}): the down direction gets the states' hop latency")
    paths = _write_latency_files(d, files, key)
    up = Dist(dist="empirical", file=str(paths["hop_up"]))
    down = Dist(dist="empirical", file=str(paths.get("hop_down", paths["hop_up"])))
    srv_down = Dist(dist="empirical", file=str(paths.get("server_down", paths["hop_up"])))
    net = replace(base.net,
                  host_link=replace(base.net.host_link, latency=up, latency_down=down),
                  server_link=replace(base.net.server_link, latency=down,
                                      latency_down=srv_down))
    hop_down = files.get("hop_down", hop_up)
    report = {
        "state_latency_mean_s": float(p["up"].mean()),
        "state_held_frac": float(p["up_held"].mean()),
        "hop_latency_mean_s": float(hop_up.mean()),
        "hop_latency_p99_s": float(np.percentile(hop_up, 99)),
        "down_latency_mean_s": float(p["down"].mean()) if p["down"].size else float("nan"),
        "down_held_frac": float(p["down_held"].mean()) if p["down"].size else float("nan"),
        "down_latencies": int(p["down"].size),
        "stalls_up": stalls_up,
        "stalls_down": stalls_down,
        "hop_down_latency_mean_s": float(hop_down.mean()),
        "hop_down_latency_p99_s": float(np.percentile(hop_down, 99)),
        "hold_tol_s": tol,
        "sender_wait_up_mean_s": float(wait_up.mean()),
        "hold_service_up_s": up_srv,
        "hold_service_down_s": down_srv,
        "path_cpu_service_up_s": cpu["up"],
        "path_cpu_service_down_s": cpu["down"],
        "server_receive_queue_mean_s": float(queue.mean()),
        "server_queue_folded_into_server_link": fold,
    }
    return net, report


def _fit_delivery(base: Scenario, w: pd.DataFrame, warn: list[str]) -> tuple[float, float]:
    """Per-client delivery service and the fan-out slope from the trigger receipts."""
    # one row per receiving client (a recording repeats a host's receipt for its nodes)
    trig = w[w["kind"] == "trigger"].drop_duplicates(["method", "frame", "host", "t_recv"])
    _, slope = fanout_slope(trig)
    same = trig.groupby(["method", "frame"]).size()
    if trig.empty or int(same.max()) < 2:
        per = base.broker.delivery_service.mean_value() * base.nodes / base.hosts
        warn.append("no trigger reached two hosts: the per-delivery service cannot be "
                    f"measured from the fan-out; kept the base's {per * 1e6:.3g} µs per client")
        return per, slope
    return max(delivery_floor(trig), 0.0), slope


def _record_bits(source: Path, warn: list[str]) -> dict[str, Any]:
    """``payload_bits`` and ``trigger_payload_bits``: the state and trigger records on
    the live run's wire (its ``summary.json`` records their bytes; a live table that does
    not is taken to be of this version's wire, warned; a run without one, silently)."""
    info = live_info(source)
    if not info:
        return {"payload_bits": STATE_BYTES * 8, "trigger_payload_bits": TRIGGER_BYTES * 8}
    state = int(recorded(info, "state_bytes", STATE_BYTES,
                         f"this version's {STATE_BYTES}-byte state record taken", warn))
    trig = int(recorded(info, "trigger_bytes", TRIGGER_BYTES,
                        f"this version's {TRIGGER_BYTES}-byte trigger record taken", warn))
    return {"payload_bits": state * 8, "trigger_payload_bits": trig * 8}


def calibrate(source: Path, files_dir: Path | None = None, strict: bool = True,
              hold_tol: float = HOLD_TOL, threads: bool = True, runq_growth: bool = False
              ) -> tuple[Scenario, dict[str, Any]]:
    """Fit a DES scenario to the live run at ``source``.

    Args:
        source: a ``sigma-des live --out`` directory (or MCAP file).
        files_dir: where to write the empirical latency files (default: next to source).
        strict: refuse incomplete inputs (hosts whose per-node rows are missing);
            False: fit from what there is and say so in ``report["warnings"]``.
        hold_tol: a delivery this close after the previous one on its connection counts
            as held behind it (s; :func:`~sigma_des.calibrate.dequeue.held`); 0 keeps the
            measured latencies as they are (nothing is held exactly together live).
        threads: fit a process's two threads apart when the run recorded them (False:
            ``--one-thread``).
        runq_growth: run-queue waits growing with load (Erlang C, ``--runq-growth``).

    Returns:
        The calibrated scenario and a report of the fitted figures (seconds), with
        ``warnings`` (what could not be fitted and what was kept instead) and, from the
        live run's ``cpu.csv``, the per-process CPU demands.

    Raises:
        ConfigError: naming the source if it holds too few messages to fit, or (strict)
            naming what is missing.
    """
    base, msgs, w, states = _window(source)
    warn: list[str] = []
    d = files_dir or (source if source.is_dir() else source.parent)
    if not (math.isfinite(hold_tol) and 0.0 <= hold_tol <= 0.01):
        raise ConfigError("--hold-tol", f"must be in 0..0.01 s, got {hold_tol}")
    fit = fit_deployment(source, base.broker.publish_service.mean_value(), warn, threads,
                         runq_growth)
    # the fan-out's figures are reported; they set the broker only without a CPU fit
    delivery, slope = _fit_delivery(base, w, warn if fit is None else [])
    if fit is None:  # no CPU stage: the fan-out's per-client delivery, the base's publish
        dep = replace(base.deployment, preset="none", background=0.0, host_demand=0.0,
                      server_demand=0.0, server_tick=0.0)
        publish, per_client = base.broker.publish_service, delivery
        cpu_report: dict[str, Any] = {}
    else:  # the broker's demand per inbound PUBLISH and per delivery; one client per host
        dep, publish = fit.deployment, Dist(dist="constant", value=fit.broker_service)
        per_client = fit.broker_service
        cpu_report = fit.report
    u = fit.report["machine_busy_cores"] / dep.cores if fit is not None else 0.0
    services = path_services(dep, publish.mean_value(), per_client,
                             fit.wake_share if fit is not None else None, u)
    net, lat_report = _fit_links(base, w, states, services, d, hold_tol, fit is None, warn,
                                 "--out" if files_dir else str(source))
    compute, step_report = fit_compute(base, msgs, states, source.suffix == ".mcap", strict,
                                       warn)
    topic_len = int(round(float(np.mean([state_topic_bytes(m, int(h))
                                         for m, h in zip(states["method"], states["host"],
                                                         strict=True)]))))
    width = make_dynamics(base).command_dim
    sc = replace(
        base,
        **_record_bits(source, warn),
        commands=replace(base.commands, payload_bits=command_bytes(width) * 8),
        net=replace(net, topic_bytes=topic_len),
        broker=BrokerSpec(publish_service=publish,
                          delivery_service=Dist(dist="constant",
                                                value=_per_delivery(per_client, base, dep))),
        compute=compute,
        deployment=dep,
    )
    report = {
        "states": int(len(states)), "hop_floor_share": floor_share(states),
        "delivery_service_per_client_s": per_client,
        **lat_report,
        "delivery_service_s": per_client,
        "delivery_floor_s": delivery,
        "fanout_slope_s": slope,
        "publish_service_s": publish.mean_value(),
        **step_report,
        **cpu_report,
        "warnings": warn,
    }
    return sc, report


def _per_delivery(per_client: float, sc: Scenario, dep: DeploymentSpec) -> float:
    """The broker's per-delivery service for ``sc``: per client as measured with one
    client per host; spread over a host's nodes (× hosts / nodes) when the DES
    delivers to every node, so a trigger's fan-out takes the measured time."""
    return per_client if dep.clients == "host" else per_client * sc.hosts / sc.nodes


def for_target(cal: Scenario, report: dict[str, Any], overrides: list[str]) -> Scenario:
    """The calibrated scenario with ``overrides`` (``key=value``) applied, the broker's
    delivery service set for the target (:func:`_per_delivery`: rescaled to its
    ``hosts / nodes`` unless the DES has one client per host)."""
    sc = apply_overrides(cal, overrides)
    per = _per_delivery(float(report["delivery_service_per_client_s"]), sc, sc.deployment)
    return replace(sc, broker=replace(sc.broker,
                                      delivery_service=Dist(dist="constant", value=per)))
