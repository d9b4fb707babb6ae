"""What a finished live run leaves: its message table, its fidelity, its live counters.

After ``stop`` every host writes a rows file (:func:`~sigma_des.live.procs.rows_file`:
its message rows and the true positions of every frame its truth stepped); with the
server's rows they make the run's timestamp table (:func:`message_table`, saved as
``messages.csv.gz``), the hosts' positions joined by frame make the formation error and
DTW against the ideal run (:func:`host_fidelity`), and the processes' counters the
live metrics (:func:`live_info`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sigma_des.config import Scenario
from sigma_des.live.clocksync import ClockBook
from sigma_des.live.procs import HostGroup, rows_file
from sigma_des.live.server import LiveServer

__all__ = ["LIVE_METRICS", "MESSAGE_COLUMNS", "host_fidelity", "live_info", "message_table"]

MESSAGE_COLUMNS = ("method", "kind", "host", "node", "frame", "t_send", "t_recv", "t_trig",
                   "cost", "republish")
LIVE_METRICS = ("rejected", "unknown_topic", "reconnects", "missed_frac", "late")


def host_fidelity(out: dict[str, Any], sc: Scenario, srv: LiveServer, d: Path, run: str) -> None:
    """Formation error and DTW against the ideal run, from the hosts' true positions.

    The hosts log every frame's true positions (as the DES engine does); frames that
    every host logged are sampled at ``fidelity.log_rate`` Hz of physics time. A host
    that did not report (killed) leaves the metrics NaN.
    """
    from sigma_des.api import ideal_run
    from sigma_des.metrics.fidelity import TrajectoryLog, add_fidelity

    n = sc.nodes
    tracks = []
    for h in range(sc.hosts):
        p = rows_file(d, run, h)
        if not p.exists():
            return
        with np.load(p) as z:
            tracks.append((z["nodes"], z["track_frames"], z["track_t"], z["track_pos"]))
    common = set(tracks[0][1].tolist())
    for tr in tracks[1:]:
        common &= set(tr[1].tolist())
    frames = np.array(sorted(common), dtype=np.int64)
    if frames.size < 2:
        return
    pos = np.zeros((frames.size, n, 3))
    t = np.zeros(frames.size)
    for nodes, fr, tt, pp in tracks:
        idx = np.searchsorted(fr, frames)
        pos[:, nodes] = pp[idx]
        t = tt[idx]
    log = TrajectoryLog(sc.fidelity.log_rate, srv.dyn.observe(srv.dyn.initial_state(n))[:, 9:12])
    for k in range(frames.size):
        log.add(float(t[k]), pos[k])
    add_fidelity(out, *log.arrays(), ideal_run(sc)[1], sc.fidelity)


def message_table(run: str, m: str, srv: LiveServer, d: Path, hosts: int,
                  book: ClockBook | None = None) -> pd.DataFrame:
    """The run's per-message rows: the server's and every host's rows file, one table
    (:data:`MESSAGE_COLUMNS`; with hosts on clocks of their own, ``book`` corrects
    their times to ours)."""
    kinds: list[np.ndarray] = [np.array([r[0] for r in srv.rows], dtype="U12")]
    vals: list[np.ndarray] = [np.array([r[1:] for r in srv.rows], dtype=np.float64).reshape(-1, 8)]
    for h in range(hosts):
        p = rows_file(d, run, h)
        if p.exists():
            with np.load(p) as z:
                kinds.append(z["kinds"].astype("U12"))
                vals.append(z["values"])
            if book is not None:  # host clock -> ours, with every exchange of the run
                from sigma_des.live.cluster import correct_rows

                vals[-1] = correct_rows(kinds[-1], vals[-1], h, book)
    v = np.concatenate(vals)
    df = pd.DataFrame(v, columns=list(MESSAGE_COLUMNS[2:]))
    df.insert(0, "kind", np.concatenate(kinds))
    df.insert(0, "method", m)
    for c in ("host", "node", "frame"):
        df[c] = df[c].astype(np.int64)
    df["republish"] = df["republish"].astype(bool)
    return df.sort_values(["kind", "frame", "node"], kind="stable").reset_index(drop=True)


def live_info(srv: LiveServer, group: HostGroup, table: pd.DataFrame,
              sc: Scenario) -> dict[str, Any]:
    """The live counters of the run (:data:`LIVE_METRICS` among them) and where its
    hosts ran."""
    st = srv.stats
    states = table[(table["kind"] == "state") & ~table["republish"]]
    trig = table[table["kind"] == "trigger_sent"]
    win = trig[(trig["t_send"] >= sc.warmup) & (trig["t_send"] < sc.duration)]
    frames = set(win["frame"].tolist())
    got = states[states["frame"].isin(frames)].drop_duplicates(["node", "frame"])
    expected = len(frames) * sc.nodes
    return {
        "rejected": srv.rejected + sum(int(s.get("rejected", 0)) for s in st.values()),
        "unknown_topic": srv.unknown_topic,
        "reconnects": max(0, srv.client.connects - 1)
        + sum(max(0, int(s.get("connects", 1)) - 1) for s in st.values()),
        "missed_frac": 1.0 - len(got) / expected if expected else float("nan"),
        "late": srv.late,
        "hosts_reported": sorted(st),
        "hosts_killed": group.killed(),
        "where": group.where(),
        "step_real_ms": 1000.0 * sum(float(s.get("step_real_s", 0)) for s in st.values())
        / max(1, sum(int(s.get("steps", 0)) for s in st.values())),
    }
