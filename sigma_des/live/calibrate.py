"""Fit the DES's network, broker and compute parameters from a live run.

From the message table (``messages.csv.gz`` or an MCAP recording), inside the
metrics window:

* **broker per-delivery service** ``broker.delivery_service``: from how a trigger's
  delivery delay grows along its fan-out (the k-th host to receive frame f waited
  for k-1 deliveries before it). The least-squares slope of delay against position
  is reported, but on a loaded machine it mostly measures how late the OS wakes
  each host process, which the hop latency already holds; the fitted service is
  the 5th percentile of the gaps between consecutive receivers
  (:func:`delivery_floor`: scheduling noise only adds to a gap, so a low quantile
  approaches the broker's own per-delivery time);
* **per-hop latency per direction** (empirical sample files): a state travels
  host -> broker -> server (``net.host_link.latency`` and
  ``net.server_link.latency_down``), a trigger or command server -> broker -> host
  (``net.server_link.latency`` and ``net.host_link.latency_down``); one hop is
  ``(path latency - publish_service - delivery_service) / 2``, the path latency
  **de-queued** first (:mod:`sigma_des.live.dequeue`: the DES's stream keeps order
  itself, so the in-order wait in the measured latencies must not be drawn again).
  The broker's publish service is not separable from the hop latency from outside
  the broker, so the base scenario's value is kept;
* **the server's receive cost** (time from the client's receipt to the loop
  handling the state): the DES has no such stage, so it is folded into the
  server link's down latency (fitted as a hop from each state's path latency plus
  twice its receive queueing, so that hop carries the whole queueing) when its mean
  exceeds 5 % of the hop's;
* **node step time** ``compute.step_time``: a lognormal with the mean and standard
  deviation of each job's service, i.e. its publish minus the time it got one of the
  host's ``cores_per_host`` cores (replayed FCFS, :func:`~sigma_des.live.dequeue.
  job_services`; the DES adds the wait for a core itself); the report also gives the
  share of the publish delay's variance common to a host's nodes in one frame
  (:func:`host_share`; the DES draws every node independently);
* **CPU service demands** of every process by the Utilization Law, and the
  background CPU (:mod:`sigma_des.live.demands`, from the run's ``cpu.csv``):
  reported only, the DES has no CPU stage yet.

What cannot be fitted is said, never filled in silently: hosts whose states arrived
without their per-node publish rows are refused (``strict``) or warned about, and too
few samples, a single receiver per trigger or a missing ``cpu.csv`` are warnings in
``report["warnings"]``. :mod:`sigma_des.live.insample` checks the result against the
run it came from.
* **wire sizes**: ``payload_bits``, ``trigger_payload_bits``, ``commands.payload_bits``
  and ``net.topic_bytes`` set to the live payloads and topics (``sigma_des.live.wire``),
  so the DES counts the same bytes.

The DES broker delivers a trigger to every *node*; live, one client per host
receives it. :func:`for_target` therefore scales the fitted per-client delivery
service by ``hosts / nodes`` of the scenario it prepares, so a trigger's total
fan-out time is the measured one.

The result is the live run's scenario with these parameters replaced, written as
TOML that ``sigma-des compare`` runs (the sample files sit next to it).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from sigma_des.config import Scenario, load, to_toml
from sigma_des.errors import ConfigError
from sigma_des.events.spec import ComputeSpec
from sigma_des.factory import make_dynamics
from sigma_des.guard import atomic_write, output_file, read_text
from sigma_des.live.cpu import CPU_FILE
from sigma_des.live.demands import fit_demands, read_cpu
from sigma_des.live.dequeue import HOLD_TOL, censored_weights, held, job_services, quantiles
from sigma_des.live.messages import read_messages
from sigma_des.live.wire import STATE_BYTES, TRIGGER_BYTES
from sigma_des.loading import from_dict
from sigma_des.net.latency import Dist
from sigma_des.net.spec import BrokerSpec, NetSpec

__all__ = ["MIN_SAMPLES", "calibrate", "calibrated_toml", "delivery_floor", "fanout_slope",
           "for_target", "report_lines"]


def fanout_slope(trig: pd.DataFrame) -> tuple[float, float]:
    """Least-squares ``(intercept, slope)`` of trigger delay vs position in its fan-out.

    Args:
        trig: rows with ``frame``, ``t_send``, ``t_recv`` (one per receiving client).

    Returns:
        Intercept (s) and slope (s per delivery); slope 0 with fewer than two receivers.
    """
    if trig.empty:
        return 0.0, 0.0
    t = trig.sort_values(["frame", "t_recv"], kind="stable")
    pos = t.groupby("frame").cumcount().to_numpy(dtype=np.float64)
    delay = (t["t_recv"] - t["t_send"]).to_numpy()
    if pos.max() < 1:
        return float(delay.mean()), 0.0
    slope, intercept = np.polyfit(pos, delay, 1)
    return float(intercept), float(slope)


def delivery_floor(trig: pd.DataFrame, q: float = 0.05) -> float:
    """The ``q`` quantile of the gaps between consecutive receivers of one trigger (s).

    Args:
        trig: rows with ``frame`` and ``t_recv`` (one per receiving client).
        q: the quantile.

    Returns:
        The quantile, 0 when no trigger had two receivers.
    """
    t = trig.sort_values(["frame", "t_recv"], kind="stable")
    same = t["frame"].to_numpy()[1:] == t["frame"].to_numpy()[:-1]
    gaps = np.diff(t["t_recv"].to_numpy())[same]
    return float(np.quantile(gaps, q)) if gaps.size else 0.0


def host_share(pub: pd.DataFrame) -> float:
    """Share of the step-time variance that is common to a host's nodes in one frame.

    Args:
        pub: ``state_pub`` rows with ``host``, ``frame`` and ``cost`` = publish minus
            trigger receipt (s).

    Returns:
        ``var(per host-and-frame means) / var(all)``: 0 if the nodes of a host vary
        independently, 1 if they always finish together; NaN with fewer than 2 rows.
    """
    c = pub["cost"]
    if len(c) < 2 or float(c.var(ddof=0)) == 0.0:
        return float("nan")
    means = pub.groupby(["host", "frame"])["cost"].transform("mean")
    return float(means.var(ddof=0) / c.var(ddof=0))


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


#: Fewer samples than this in a fit is warned about (the fit uses them all the same).
MIN_SAMPLES = 20


def _hop_samples(x: NDArray[np.float64], held_: NDArray[np.bool_], services: float
                 ) -> NDArray[np.float64]:
    """Per-hop draws from path latencies ``x`` (host -> broker -> receiver): the
    de-queued path latency (:mod:`sigma_des.live.dequeue`) less the broker's services,
    split evenly over the two hops; one sample per message, ascending."""
    xs, w = censored_weights(x, held_)
    return np.clip((quantiles(xs, w, x.size) - services) / 2.0, 0.0, None)


def _paths(w: pd.DataFrame, states: pd.DataFrame, tol: float) -> dict[str, Any]:
    """Path latencies of both directions, with the in-order holds flagged.

    Up (states): one in-order stream per method into the server (the DES's server
    connection carries every state). Down (triggers and commands): one per method and
    receiving host. Rows of one receipt (a recording repeats a host's trigger per node)
    count once.
    """
    up_conn = pd.factorize(states["method"])[0]
    lat_up = (states["t_recv"] - states["t_send"]).to_numpy()
    down = w[w["kind"].isin(("trigger", "command"))].drop_duplicates(
        ["method", "kind", "frame", "host", "t_recv"])
    down = down[np.isfinite(down["t_recv"])]
    down_conn = pd.factorize(down["method"].astype(str) + "/" + down["host"].astype(str))[0]
    return {
        "up": lat_up,
        "up_held": held(up_conn, states["t_send"], states["t_recv"], tol),
        "down": (down["t_recv"] - down["t_send"]).to_numpy(),
        "down_held": held(down_conn, down["t_send"], down["t_recv"], tol),
    }


def _write_latency_files(d: Path, files: dict[str, NDArray[np.float64]], key: str
                         ) -> dict[str, Path]:
    """Write each sample array as ``<name>.txt`` in ``d`` (all or nothing per file:
    :func:`~sigma_des.guard.atomic_write`); their paths by name. ``key`` is named in
    an error."""
    out = {}
    for name, samples in files.items():
        out[name] = output_file(d / f"{name}.txt", key)
        atomic_write(out[name], partial(np.savetxt, X=samples, fmt="%.9g"), key)
    return out


def _publish_costs(msgs: pd.DataFrame, base: Scenario) -> pd.DataFrame:
    """The window's ``state_pub`` rows with ``raw`` = publish minus trigger receipt and
    ``cost`` = the job's service without its wait for one of the host's
    ``cores_per_host`` cores (:func:`~sigma_des.live.dequeue.job_services`, replayed over
    the whole run per method, so jobs queued before the window count)."""
    pub = msgs[msgs["kind"] == "state_pub"]
    pub = pub[np.isfinite(pub["t_trig"]) & (pub["t_send"] >= pub["t_trig"])]
    host = pub["method"].astype(str) + "/" + pub["host"].astype(str)
    cost = job_services(host, pub["node"], pub["t_trig"], pub["t_send"], base.cores_per_host)
    pub = pub.assign(raw=pub["t_send"] - pub["t_trig"], cost=cost)
    return pub[(pub["t_send"] >= base.warmup) & (pub["t_send"] < base.duration)]


def _fit_links(base: Scenario, w: pd.DataFrame, states: pd.DataFrame, delivery: float,
               d: Path, tol: float, warn: list[str], key: str = "--out"
               ) -> tuple[NetSpec, dict[str, Any]]:
    """Per-direction de-queued hop latencies (and the server's receive queue) as the
    links' empirical latency files (see the module doc)."""
    services = base.broker.publish_service.mean_value() + delivery
    p = _paths(w, states, tol)
    if p["up"].size < MIN_SAMPLES:
        warn.append(f"only {p['up'].size} state latencies in the window (< {MIN_SAMPLES})")
    hop_up = _hop_samples(p["up"], p["up_held"], services)
    queue = np.nan_to_num(np.clip((states["t_trig"] - states["t_recv"]).to_numpy(), 0.0, None))
    fold = float(queue.mean()) > 0.05 * float(hop_up.mean())
    files = {"hop_up": hop_up}
    if fold:  # the DES has no server receive stage: the server link's down hop carries it
        files["server_down"] = _hop_samples(p["up"] + 2.0 * queue, p["up_held"], services)
    if p["down"].size >= MIN_SAMPLES:
        files["hop_down"] = _hop_samples(p["down"], p["down_held"], services)
    else:
        warn.append(f"only {p['down'].size} trigger/command latencies in the window "
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
        "hop_down_latency_mean_s": float(hop_down.mean()),
        "hop_down_latency_p99_s": float(np.percentile(hop_down, 99)),
        "hold_tol_s": tol,
        "server_receive_queue_mean_s": float(queue.mean()),
        "server_queue_folded_into_server_link": fold,
    }
    return net, report


def _fit_compute(base: Scenario, msgs: pd.DataFrame, states: pd.DataFrame, recording: bool,
                 strict: bool, warn: list[str]) -> tuple[ComputeSpec, dict[str, Any]]:
    """The node step time from the hosts' per-node publish rows, refusing (``strict``)
    or warning when hosts whose states arrived left none."""
    pub = _publish_costs(msgs, base)
    keep = base.compute.step_time
    kept = f"compute.step_time kept from the base scenario ({keep.dist}, mean " \
           f"{keep.mean_value() * 1e3:.3g} ms)"
    if recording:
        warn.append(f"an MCAP recording has no per-node publish rows: {kept}")
    else:
        sent = set(zip(states["method"], states["host"], strict=True))
        rows = set(zip(pub["method"], pub["host"], strict=True))
        missing = sorted(f"{m}/host{int(h)}" for m, h in sent - rows)
        if missing:
            msg = (f"no per-node publish rows (state_pub) from {', '.join(missing)} although "
                   "their states arrived")
            if strict:
                raise ConfigError("state_pub", msg + "; rerun the live run, or pass "
                                  "--allow-incomplete to fit without them")
            warn.append(msg + ("; fitted from the other hosts" if len(pub) else f"; {kept}"))
    cost = pub["cost"].to_numpy()
    if 0 < cost.size < MIN_SAMPLES:
        warn.append(f"only {cost.size} per-node publish rows (< {MIN_SAMPLES}) for the "
                    "step time")
    if not cost.size:
        return base.compute, {"step_time_mean_s": keep.mean_value(),
                              "step_time_std_s": keep.std, "step_time_host_share": float("nan"),
                              "step_time_samples": 0}
    mean, std = float(cost.mean()), float(cost.std()) if cost.size > 1 else 0.0
    spec = ComputeSpec(step_time=Dist(dist="lognormal", mean=max(mean, 1e-7), std=std))
    return spec, {"step_time_mean_s": mean, "step_time_std_s": std,
                  "step_time_with_core_wait_mean_s": float(pub["raw"].mean()),
                  "step_time_host_share": host_share(pub.assign(cost=pub["raw"])),
                  "step_time_samples": int(cost.size)}


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


def _fit_demands(source: Path, warn: list[str]) -> dict[str, Any]:
    """The Utilization-Law demands (:mod:`sigma_des.live.demands`) as report entries."""
    cpu = read_cpu(source)
    if cpu is None:
        warn.append(f"no {CPU_FILE} next to the source: CPU service demands not fitted")
        return {}
    table, bg, w = fit_demands(cpu)
    warn.extend(w)
    return {"cpu_demands": table.to_dict("records"), "background_cores": bg}


def calibrate(source: Path, files_dir: Path | None = None, strict: bool = True,
              hold_tol: float = HOLD_TOL) -> tuple[Scenario, dict[str, Any]]:
    """Fit a DES scenario to the live run at ``source``.

    Args:
        source: a ``sigma-des live --out`` directory (or MCAP file).
        files_dir: where to write the empirical latency files (default: next to source).
        strict: refuse incomplete inputs (hosts whose per-node rows are missing);
            False: fit from what there is and say so in ``report["warnings"]``.
        hold_tol: a delivery this close after the previous one on its connection counts
            as held behind it (s; :func:`~sigma_des.live.dequeue.held`); 0 keeps the
            measured latencies as they are (nothing is held exactly together live).

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
    delivery, slope = _fit_delivery(base, w, warn)
    d = files_dir or (source if source.is_dir() else source.parent)
    if not (math.isfinite(hold_tol) and 0.0 <= hold_tol <= 0.01):
        raise ConfigError("--hold-tol", f"must be in 0..0.01 s, got {hold_tol}")
    net, lat_report = _fit_links(base, w, states, delivery, d, hold_tol, warn,
                                 "--out" if files_dir else str(source))
    compute, step_report = _fit_compute(base, msgs, states, source.suffix == ".mcap", strict,
                                        warn)
    topic_len = int(round(float(np.mean([len(f"sd/{'x' * 8}{m}/up/h{int(h)}/state")
                                         for m, h in zip(states["method"], states["host"],
                                                         strict=True)]))))
    width = make_dynamics(base).command_dim
    sc = replace(
        base,
        payload_bits=STATE_BYTES * 8,
        trigger_payload_bits=TRIGGER_BYTES * 8,
        commands=replace(base.commands, payload_bits=(23 + 8 * width) * 8),
        net=replace(net, topic_bytes=topic_len),
        broker=BrokerSpec(publish_service=base.broker.publish_service,
                          delivery_service=Dist(dist="constant",
                                                value=delivery * base.hosts / base.nodes)),
        compute=compute,
    )
    report = {
        "states": int(len(states)),
        "delivery_service_per_client_s": delivery,
        **lat_report,
        "delivery_service_s": delivery,
        "fanout_slope_s": slope,
        "publish_service_s": base.broker.publish_service.mean_value(),
        **step_report,
        **_fit_demands(source, warn),
        "warnings": warn,
    }
    return sc, report


def for_target(cal: Scenario, report: dict[str, Any], overrides: list[str]) -> Scenario:
    """The calibrated scenario with ``overrides`` (``key=value``) applied, the broker's
    delivery service rescaled to the target's ``hosts / nodes`` (see the module doc)."""
    sc = apply_overrides(cal, overrides)
    per = float(report["delivery_service_per_client_s"]) * sc.hosts / sc.nodes
    return replace(sc, broker=replace(sc.broker,
                                      delivery_service=Dist(dist="constant", value=per)))


def report_lines(report: dict[str, Any]) -> list[str]:
    """The report as readable lines: the fitted figures (``key = value``), the CPU
    demands, the in-sample errors (flagged cells marked) and the warnings."""
    lines = [f"{k} = {v}" for k, v in report.items() if not isinstance(v, list | dict)]
    for m, cores in report.get("background_cores", {}).items():
        lines.append(f"background_cores.{m} = {cores:.3f} (CPU other processes used)")
    for r in report.get("cpu_demands", []):
        lines.append(f"cpu demand {r['method']}/{r['process']}: {r['demand_s'] * 1e6:.1f} "
                     f"µs per message ({r['messages']:.0f} messages, busy {r['busy_s']:.3f} s "
                     f"of {r['window_s']:.2f} s, idle rate {r['idle_rate']:.4f})")
    for r in report.get("in_sample", []):
        unit = "pp" if r["metric"] == "missed_frac" else "%"
        lines.append(f"in-sample {r['method']} {r['metric']}: live {r['live']:.4g}, DES "
                     f"{r['des']:.4g}, error {100 * r['error']:+.1f} {unit}"
                     + ("  > 10: FLAGGED" if r["flagged"] else ""))
    cells = [r for r in report.get("in_sample", []) if math.isfinite(r["error"])]
    if cells:
        ok = sum(not r["flagged"] for r in cells)
        lines.append(f"in-sample: {ok} of {len(cells)} cells within 10 % (10 pp)")
    lines += [f"warning: {w}" for w in report.get("warnings", [])]
    return lines


def calibrated_toml(sc: Scenario, report: dict[str, Any]) -> str:
    """The calibrated scenario as TOML, the report (:func:`report_lines`) as a comment
    header."""
    head = ["# calibrated by `sigma-des calibrate` from a live run"]
    head += [f"# {line}" for line in report_lines(report)]
    return "\n".join(head) + "\n" + to_toml(sc)
