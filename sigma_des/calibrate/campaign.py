"""A calibration from a short campaign of live runs, and the background a calibration keeps.

``sigma-des calibrate RUN [RUN...]`` fits each run on its own
(:func:`~sigma_des.calibrate.fit.calibrate`, its sample files in ``run<i>/``) and
combines them (:func:`combine`), each parameter from the runs that show it:

* the hop latencies (every empirical link latency): the per-node runs' samples pooled
  (every run's when none is per node), with their states-weighted nodes per host
  (``hop_nodes_per_host``, which :mod:`~sigma_des.calibrate.burst` rescales from);
* the per-message CPU of each process kind (``*_demand``, ``*_wake``, the network
  thread's ``*_net_*``, the parts beside the thread ``*_wake_side``, the run-queue
  waits ``*_runq``) and the broker's services: the mean over the per-node runs with a
  CPU stage (every run with one when none is per node);
* the CPU of a bundle's further records (``host_record``, ``server_record``): the mean
  over the **bundled** runs, which are the ones where a loop handles several records
  of one message (the per-node runs' figure when there is none);
* the step time and its host share, the scenario's keys and the cores: the primary
  run (:func:`~sigma_des.calibrate.primary.primary_run`), which the hop match re-runs.

The report's ``parameter_sources`` names the runs of each, ``runs`` each run's fit. Runs
of different scenarios are refused (:func:`check_combinable`).

**The background.** Other processes' CPU during a run (``background_cores_measured``)
slows that run's bursts, and the fit takes it out of the demands and the hops; it is a
property of the calibration machine at that moment, not of the target. The calibrated
scenario therefore gets ``deployment.background`` = the target's (0 unless ``calibrate
--background`` says otherwise), and a run whose background exceeded
:data:`UNDER_LOAD` of the cores is warned about (its run-queue waits hold the others'
load too). The hop match and the in-sample check run each live run with its own
measured background, since they reproduce that run.
"""

from __future__ import annotations

import json
import math
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.calibrate.primary import primary_run
from sigma_des.config import Scenario
from sigma_des.errors import ConfigError
from sigma_des.net.latency import Dist, load_samples

__all__ = ["MAY_DIFFER", "UNDER_LOAD", "RunInfo", "check_combinable", "combine", "loaded_runs",
           "refuse_loaded", "run_info", "under_load_warning", "with_background"]

#: Scenario keys the runs of one campaign may differ in (besides the message mode).
MAY_DIFFER = frozenset({"nodes", "hosts", "duration", "warmup", "seed"})
#: A run whose background CPU exceeds this share of the cores was under load.
UNDER_LOAD = 0.25
#: Deployment keys that are per-message costs or waits (and the loop's hand-over
#: interval): shown by every run.
_PER_MESSAGE = ("host_demand", "server_demand", "host_wake", "server_wake", "host_wake_side",
                "server_wake_side", "host_net_wake", "server_net_wake", "host_net_msg",
                "server_net_msg", "host_runq", "server_runq", "broker_runq", "lock_switch")
#: Deployment keys shown by bundled runs.
_PER_RECORD = ("host_record", "server_record")


class RunInfo(dict):  # type: ignore[type-arg]
    """What a live run's ``summary.json`` says: ``name``, ``scenario`` (flat dotted
    keys), ``bundle``, ``cores``, the measured ``background`` (cores, NaN unknown) and
    ``figures`` (its ``methods`` table: per method, per metric, the value)."""


def _flat(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flat(v, key + "."))
        else:
            out[key] = v
    return out


def run_info(source: Path) -> RunInfo:
    """The facts of the live run at ``source`` (a ``sigma-des live --out`` directory)."""
    d = source if source.is_dir() else source.parent
    try:
        summ = json.loads((d / "summary.json").read_text())
    except (OSError, ValueError):  # the fit refuses a broken summary, naming it
        summ = {}
    summ = summ if isinstance(summ, dict) else {}
    got = summ.get("live")
    live: dict[str, Any] = got if isinstance(got, dict) else {}
    bundle = any(bool(v.get("bundle")) for v in live.values() if isinstance(v, dict))
    cores = next((int(v["cores"]) for v in live.values()
                  if isinstance(v, dict) and v.get("cores")), 0)
    bg = []
    for v in live.values():
        for r in (v.get("cpu", []) if isinstance(v, dict) else []):
            if r.get("process") == "background" and r.get("window_s", 0) > 0:
                bg.append(float(r["cpu_s"]) / float(r["window_s"]))
    scen = summ.get("scenario")
    methods = summ.get("methods")
    figures = {str(m): v for m, v in methods.items() if isinstance(v, dict)} if isinstance(
        methods, dict) else {}
    return RunInfo(name=str(source), scenario=_flat(scen if isinstance(scen, dict) else {}),
                   bundle=bundle, cores=cores,
                   background=float(np.mean(bg)) if bg else math.nan, figures=figures)


def check_combinable(infos: list[RunInfo]) -> None:
    """Refuse runs that are not one scenario at several sizes and message modes.

    Raises:
        ConfigError: (the first key that differs, e.g. ``f_trig``) naming both runs;
            (``cores``) runs on machines with different core counts.
    """
    first = infos[0]
    for other in infos[1:]:
        keys = sorted(set(first["scenario"]) | set(other["scenario"]))
        for k in keys:
            if k.split(".")[0] in MAY_DIFFER or k.startswith("deployment."):
                continue
            a, b = first["scenario"].get(k), other["scenario"].get(k)
            if a != b:
                raise ConfigError(k, f"differs between the runs {first['name']} ({a!r}) and "
                                  f"{other['name']} ({b!r}): a calibration combines runs of "
                                  f"one scenario (only {', '.join(sorted(MAY_DIFFER))} and "
                                  "the message mode may differ)")
        if first["cores"] and other["cores"] and first["cores"] != other["cores"]:
            raise ConfigError("cores", f"{first['name']} ran on {first['cores']} cores, "
                              f"{other['name']} on {other['cores']}: one machine, please")


def under_load_warning(info: RunInfo) -> str | None:
    """The warning for a run under load (background above :data:`UNDER_LOAD` of its
    cores), else None."""
    bg, cores = info["background"], info["cores"]
    if cores and math.isfinite(bg) and bg > UNDER_LOAD * cores:
        return (f"{info['name']} ran under load: other processes used {bg:.2f} of its "
                f"{cores} cores (more than {UNDER_LOAD:.0%}); the fit takes their CPU out of "
                "the demands and hops, but its run-queue waits hold their load too; "
                "`predict` and `capacity` refuse this calibration without --allow-load: "
                "calibrate on a quieter machine")
    return None


def loaded_runs(report: dict[str, Any], cores: int) -> dict[str, float]:
    """``{run: background cores}`` of a calibration's runs that ran under load (above
    :data:`UNDER_LOAD` of ``cores``), from its report (``calibrate`` writes them)."""
    bgs = report.get("background_cores_of_runs")
    if not isinstance(bgs, dict) or cores <= 0:
        return {}
    return {str(k): float(v) for k, v in bgs.items()
            if isinstance(v, int | float) and math.isfinite(v) and v > UNDER_LOAD * cores}


def refuse_loaded(report: dict[str, Any], cores: int, allow: bool) -> None:
    """Refuse to predict from a calibration made under load, unless ``allow``.

    A loaded machine's run-queue waits, CPU per message and hop latencies are all
    larger than an idle one's, and the fit cannot tell them apart from the machine's
    own: the prediction of an idle target comes out too slow.

    Raises:
        ConfigError: (``--allow-load``) a run ran under load and ``allow`` is False.
    """
    loaded = loaded_runs(report, cores)
    if loaded and not allow:
        runs = ", ".join(f"{k} ({v:.2f} of {cores} cores)" for k, v in loaded.items())
        raise ConfigError("--allow-load", f"the calibration ran under load: other processes "
                          f"used more than {UNDER_LOAD:.0%} of the cores during {runs}; its "
                          "predictions of an idle machine are too slow. Calibrate on a "
                          "quieter machine, or give --allow-load to predict anyway")


def with_background(sc: Scenario, background: float) -> Scenario:
    """``sc`` with ``deployment.background`` set (kept below the cores).

    Raises:
        ConfigError: (``--background``) not in ``[0, cores)``.
    """
    if sc.deployment.preset == "none":
        return sc
    if not (math.isfinite(background) and 0.0 <= background < sc.deployment.cores):
        raise ConfigError("--background", f"must be in [0, {sc.deployment.cores}) cores, "
                          f"got {background}")
    return replace(sc, deployment=replace(sc.deployment, background=background))


def _pool_latencies(scs: list[Scenario], d: Path) -> dict[tuple[str, str], Dist]:
    """Each empirical link latency's samples over ``scs``, pooled into ``d``."""
    out: dict[tuple[str, str], Dist] = {}
    written: dict[tuple[str, ...], Path] = {}  # links sharing one sample set share a file
    for link in ("host_link", "server_link"):
        for attr in ("latency", "latency_down"):
            dists = [getattr(getattr(sc.net, link), attr) for sc in scs]
            if not dists or any(x is None or x.dist != "empirical" for x in dists):
                continue
            files = tuple(dict.fromkeys(x.file for x in dists))
            if len(files) == 1:
                continue
            if files not in written:
                # sorted: the pooled samples (and so every draw from them) do not depend
                # on the order the runs were given in; written anew, never a file an
                # earlier calibration left in ``d``
                samples = np.sort(np.concatenate([np.asarray(load_samples(f))
                                                  for f in files]))
                path = d / f"{Path(files[0]).stem}_pooled.txt"
                np.savetxt(path, samples, fmt="%.9g")
                written[files] = path
            out[(link, attr)] = Dist(dist="empirical", file=str(written[files]))
    return out


def _mean(values: list[float], weights: list[float] | None = None) -> float:
    """The (weighted) mean, exactly rounded (``math.fsum``): the same whatever the order
    of the runs."""
    w = [1.0] * len(values) if weights is None else weights
    return math.fsum(v * x for v, x in zip(values, w, strict=True)) / math.fsum(w)


def _mean_of(scs: list[Scenario], name: str) -> float:
    return _mean([float(getattr(sc.deployment, name)) for sc in scs])


def combine(fits: list[tuple[Scenario, dict[str, Any], RunInfo]], d: Path
            ) -> tuple[Scenario, dict[str, Any], int]:
    """One calibrated scenario from several runs' fits (see the module doc).

    Returns:
        The scenario, the combined report and the index of the primary run.
    """
    node = [i for i, (_, _, inf) in enumerate(fits) if not inf["bundle"]]
    bundled = [i for i, (_, _, inf) in enumerate(fits) if inf["bundle"]]
    primary, rule = primary_run([{"name": inf["name"], "bundle": inf["bundle"],
                                  "nodes": f.nodes, "hosts": f.hosts,
                                  "figures": inf.get("figures", {})} for f, _, inf in fits])
    sc, rep, _ = fits[primary]
    names = [inf["name"] for _, _, inf in fits]
    lat_runs = node or list(range(len(fits)))
    pooled = _pool_latencies([fits[i][0] for i in lat_runs], d)
    net = sc.net
    for (link, attr), dist in pooled.items():
        net = replace(net, **{link: replace(getattr(net, link), **{attr: dist})})
    cpu = [i for i in range(len(fits)) if fits[i][0].deployment.preset != "none"]
    msg_runs = [i for i in lat_runs if i in cpu] or cpu
    rec_runs = [i for i in bundled if i in cpu] or msg_runs
    dep, broker = sc.deployment, sc.broker
    new: dict[str, Any] = {}  # one replace: a record's CPU may not exceed its demand
    if msg_runs:
        new = {k: _mean_of([fits[i][0] for i in msg_runs], k)
               for k in _PER_MESSAGE if k in {f.name for f in fields(dep)}}
        svc = _mean([fits[i][0].broker.publish_service.mean_value() for i in msg_runs])
        broker = replace(broker, publish_service=Dist(dist="constant", value=svc))
    if rec_runs:
        for k in _PER_RECORD:
            demand = k.replace("record", "demand")
            new[k] = min(_mean_of([fits[i][0] for i in rec_runs], k),
                         new.get(demand, getattr(dep, demand)))
    if new:
        dep = replace(dep, **new)
    per_client = _mean([float(fits[i][1]["delivery_service_per_client_s"])
                        for i in (msg_runs or lat_runs)])
    sc = replace(sc, net=net, deployment=dep, broker=broker)
    out = {k: v for k, v in rep.items() if not isinstance(v, dict | list)}
    w = [float(fits[i][1].get("states", 0)) or 1.0 for i in lat_runs]
    m = [fits[i][0].nodes / fits[i][0].hosts for i in lat_runs]
    out.update({
        "delivery_service_per_client_s": per_client,
        # the host burst the pooled state-hop samples hold (sigma_des.calibrate.burst)
        "hop_nodes_per_host": _mean(m, w),
        "lock_switch_s": dep.lock_switch,
        "primary_run": names[primary],
        "primary_rule": rule,
        "parameter_sources": {
            "hop latencies (pooled samples)": [names[i] for i in lat_runs],
            "per-message CPU, run-queue waits, hand-over interval, broker services":
                [names[i] for i in msg_runs],
            "per-record CPU of bundles": [names[i] for i in rec_runs],
            "step time, host share, scenario keys, cores": [names[primary]],
            "broker per-delivery service": [names[i] for i in (msg_runs or lat_runs)],
        },
        "runs": {inf["name"]: {"nodes": s.nodes, "hosts": s.hosts, "bundle": inf["bundle"],
                               "background_cores_measured": inf["background"],
                               "fit": {k: v for k, v in r.items()
                                       if not isinstance(v, dict | list)}}
                 for s, r, inf in fits},
        "warnings": [w for _, r, _ in fits for w in r.get("warnings", [])],
    })
    return sc, out, primary
