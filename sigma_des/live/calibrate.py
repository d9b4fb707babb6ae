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
* **per-hop latency** (``net.host_link.latency``, an empirical sample file): a
  state travels host -> broker -> server, so one hop is
  ``(state latency - publish_service - delivery_service) / 2``; the broker's
  publish service is not separable from the hop latency from outside the broker,
  so the base scenario's value is kept;
* **the server's receive cost** (time from the client's receipt to the loop
  handling the state): the DES has no such stage, so it is folded into the
  server link's latency (``net.server_link.latency``: hop + receive queueing,
  sampled pairwise) when its mean exceeds 5 % of the hop's;
* **node step time** ``compute.step_time``: a lognormal with the mean and standard
  deviation of (state publish - trigger receipt) per job; the report also gives the
  share of its variance common to a host's nodes in one frame (:func:`host_share`;
  the DES draws every node independently);
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
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from sigma_des.config import Scenario, from_dict, load, to_toml
from sigma_des.errors import ConfigError
from sigma_des.factory import make_dynamics
from sigma_des.live.messages import read_messages
from sigma_des.live.wire import STATE_BYTES, TRIGGER_BYTES
from sigma_des.net.latency import Dist
from sigma_des.net.spec import BrokerSpec
from sigma_des.specs import ComputeSpec

__all__ = ["calibrate", "calibrated_toml", "delivery_floor", "fanout_slope", "for_target"]


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


def _base_scenario(source: Path, msgs: pd.DataFrame) -> Scenario:
    if source.suffix == ".mcap":
        d = _mcap_scenario(source)
        if d is not None:
            return from_dict(Scenario, d)  # type: ignore[no-any-return]
    summ = (source if source.is_dir() else source.parent) / "summary.json"
    if summ.exists():
        d = json.loads(summ.read_text())["scenario"]
        return from_dict(Scenario, d)  # type: ignore[no-any-return]
    n = int(msgs["node"].max()) + 1
    return Scenario(nodes=n, hosts=min(n, max(1, int(msgs.get("host", pd.Series([0])).max()) + 1)))


def _window(source: Path) -> tuple[Scenario, pd.DataFrame, pd.DataFrame]:
    """The base scenario, the messages in its run window and the (first-sent) states."""
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
    return base, w, states


def _write_latency_files(
    d: Path, hop: NDArray[np.float64], queue: NDArray[np.float64]
) -> tuple[Path, Path, bool]:
    """Write the per-hop latency file (and the server-link one when the server's receive
    queue is worth folding in); returns both paths and whether it was folded."""
    fold = float(queue.mean()) > 0.05 * float(hop.mean())
    d.mkdir(parents=True, exist_ok=True)
    hop_file = d / "hop_latency.txt"
    np.savetxt(hop_file, hop, fmt="%.9g")
    srv_file = hop_file
    if fold:
        srv_file = d / "server_latency.txt"
        np.savetxt(srv_file, hop + queue, fmt="%.9g")
    return hop_file, srv_file, fold


def _publish_costs(w: pd.DataFrame) -> pd.DataFrame:
    """``state_pub`` rows with ``cost`` = publish minus trigger receipt (finite, >= 0)."""
    pub = w[w["kind"] == "state_pub"]
    pub = pub.assign(cost=pub["t_send"] - pub["t_trig"])
    return pub[np.isfinite(pub["cost"]) & (pub["cost"] >= 0)]


def calibrate(source: Path, files_dir: Path | None = None) -> tuple[Scenario, dict[str, Any]]:
    """Fit a DES scenario to the live run at ``source``.

    Args:
        source: a ``sigma-des live --out`` directory (or MCAP file).
        files_dir: where to write the empirical latency files (default: next to source).

    Returns:
        The calibrated scenario and a report of the fitted figures (seconds).

    Raises:
        ConfigError: naming the source if it holds too few messages to fit.
    """
    base, w, states = _window(source)
    # one row per receiving client (a recording repeats a host's receipt for its nodes)
    trig = w[w["kind"] == "trigger"].drop_duplicates(["frame", "host", "t_recv"])
    _, slope = fanout_slope(trig)
    delivery = max(delivery_floor(trig), 0.0)
    publish = base.broker.publish_service.mean_value()
    lat = (states["t_recv"] - states["t_send"]).to_numpy()
    hop = np.clip((lat - publish - delivery) / 2.0, 0.0, None)
    queue = np.nan_to_num(np.clip((states["t_trig"] - states["t_recv"]).to_numpy(), 0.0, None))
    d = files_dir or (source if source.is_dir() else source.parent)
    hop_file, srv_file, fold = _write_latency_files(d, hop, queue)
    pub = _publish_costs(w)
    cost = pub["cost"].to_numpy()
    step_mean = float(cost.mean()) if cost.size else base.compute.step_time.mean_value()
    step_std = float(cost.std()) if cost.size > 1 else base.compute.step_time.std
    net = base.net
    topic_len = int(round(float(np.mean([len(f"sd/{'x' * 8}{m}/up/h{int(h)}/state")
                                         for m, h in zip(states["method"], states["host"],
                                                         strict=True)]))))
    width = make_dynamics(base).command_dim
    sc = replace(
        base,
        payload_bits=STATE_BYTES * 8,
        trigger_payload_bits=TRIGGER_BYTES * 8,
        commands=replace(base.commands, payload_bits=(23 + 8 * width) * 8),
        net=replace(
            net,
            topic_bytes=topic_len,
            host_link=replace(net.host_link, latency=Dist(dist="empirical", file=str(hop_file))),
            server_link=replace(net.server_link,
                                latency=Dist(dist="empirical", file=str(srv_file))),
        ),
        broker=BrokerSpec(publish_service=base.broker.publish_service,
                          delivery_service=Dist(dist="constant",
                                                value=delivery * base.hosts / base.nodes)),
        compute=ComputeSpec(step_time=Dist(dist="lognormal", mean=max(step_mean, 1e-7),
                                           std=step_std))
        if cost.size else base.compute,  # a recording has no publish rows: keep the base's
    )
    report = {
        "states": int(len(states)),
        "delivery_service_per_client_s": delivery,
        "state_latency_mean_s": float(lat.mean()),
        "hop_latency_mean_s": float(hop.mean()),
        "hop_latency_p99_s": float(np.percentile(hop, 99)),
        "delivery_service_s": delivery,
        "fanout_slope_s": slope,
        "publish_service_s": publish,
        "server_receive_queue_mean_s": float(queue.mean()),
        "server_queue_folded_into_server_link": fold,
        "step_time_mean_s": step_mean,
        "step_time_std_s": step_std,
        "step_time_host_share": host_share(pub),
    }
    return sc, report


def for_target(cal: Scenario, report: dict[str, Any], overrides: list[str]) -> Scenario:
    """The calibrated scenario with ``overrides`` (``key=value``) applied, the broker's
    delivery service rescaled to the target's ``hosts / nodes`` (see the module doc)."""
    sc = apply_overrides(cal, overrides)
    per = float(report["delivery_service_per_client_s"]) * sc.hosts / sc.nodes
    return replace(sc, broker=replace(sc.broker,
                                      delivery_service=Dist(dist="constant", value=per)))


def calibrated_toml(sc: Scenario, report: dict[str, Any]) -> str:
    """The calibrated scenario as TOML, the fitted figures as a comment header."""
    head = ["# calibrated by `sigma-des calibrate` from a live run"]
    head += [f"# {k} = {v}" for k, v in report.items()]
    return "\n".join(head) + "\n" + to_toml(sc)
