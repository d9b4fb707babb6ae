"""The live run's per-message timestamp table: write, read, and record to MCAP.

``messages.csv.gz`` holds one row per message event, columns
:data:`~sigma_des.live.runner.MESSAGE_COLUMNS`:

* ``trigger_sent`` (server): ``frame``, ``t_send``;
* ``trigger`` (host ``host`` received it): ``t_send``, ``t_recv``;
* ``state_pub`` (host published node ``node``'s state of ``frame``): ``t_send``,
  ``t_trig`` (when the trigger that started the job arrived) and ``cost`` (the
  drawn step delay, s);
* ``state`` (server received it): ``t_send``, ``t_recv``, ``t_trig`` = when the
  server's loop handled it (its receive queueing), ``republish``;
* ``command`` (host received node ``node``'s command of tick ``frame``).

All times are seconds since the method's first trigger on one monotonic clock.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sigma_des.config import to_dict
from sigma_des.errors import ConfigError

__all__ = ["read_messages", "record_messages", "write_messages"]

FILE = "messages.csv.gz"


def write_messages(df: pd.DataFrame, out_dir: Path) -> Path:
    """Write ``messages.csv.gz`` into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / FILE
    df.to_csv(path, index=False, float_format="%.9g")
    return path


def read_messages(source: Path) -> pd.DataFrame:
    """The message table of a live ``--out`` directory (or its ``messages.csv.gz``), or of
    an MCAP recording (through ``sigma_des.record.read_table``).

    Raises:
        ConfigError: naming the path if it is missing or not a live output.
    """
    if source.suffix == ".mcap":
        try:
            from sigma_des.record import read_table
        except ImportError:
            raise ConfigError(str(source), "reading MCAP needs sigma_des.record") from None
        return read_table(source)
    path = source / FILE if source.is_dir() else source
    if not path.exists():
        raise ConfigError(str(source), f"no {FILE} here: pass a `sigma-des live --out` directory")
    df = pd.read_csv(path)
    need = {"method", "kind", "node", "frame", "t_send", "t_recv"}
    if not need <= set(df.columns):
        raise ConfigError(str(path), f"missing columns {sorted(need - set(df.columns))}")
    return df


def record_messages(recorder_cls: Any, path: str, res: Any, msgs: pd.DataFrame,
                    kept: dict[str, dict[str, list[Any]]]) -> None:
    """Write the live run to an MCAP file through the recorder API (``sigma_des.record``).

    Triggers are recorded once per node on the receiving host, states with their pose,
    commands with their values; aligned snapshots and render samples as kept by the
    server (``kept[method]``, see ``LiveServer.kept``).
    """
    sc = res.scenario
    host_of = np.asarray(sc.host_of)
    with recorder_cls(path, scenario=to_dict(sc), mode="full") as rec:
        for method in res.methods:
            run = rec.run(method, mode="live")
            m = msgs[msgs["method"] == method]
            for r in m[m["kind"] == "trigger"].itertuples():
                for i in np.flatnonzero(host_of == r.host).tolist():
                    run.trigger(frame=int(r.frame), node=i, t_send=float(r.t_send),
                                t_recv=float(r.t_recv))
            k = kept.get(method, {})
            for (node, frame, ts, tr), obs in zip(k.get("states", []), k.get("obs", []),
                                                  strict=True):
                run.state(node=node, frame=frame, t_send=ts, t_recv=tr,
                          pos=tuple(obs[9:12]), vel=tuple(obs[0:3]), att=tuple(obs[3:6]))
            for r in m[m["kind"] == "command"].itertuples():
                run.command(node=int(r.node), frame=int(r.frame), t_send=float(r.t_send),
                            t_recv=float(r.t_recv), values=())
            for t, frame, frames, pos in k.get("snapshots", []):
                run.snapshot(t=t, frame=frame, frames=frames, pos=pos)
            for t, aoi in k.get("renders", []):
                run.render(t=t, aoi=aoi)
