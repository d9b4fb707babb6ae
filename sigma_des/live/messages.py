"""The live run's per-message timestamp table: write, read, and record to MCAP.

``messages.csv.gz`` holds one row per message event, columns
:data:`~sigma_des.live.results.MESSAGE_COLUMNS`:

* ``trigger_sent`` (server): ``frame``, ``t_send`` (the trigger's issue time, as the collector
  counts triggers: the publish stamp, µs later, could fall on the other side of a window edge);
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

import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from sigma_des.config import to_dict
from sigma_des.errors import ConfigError

__all__ = ["read_messages", "record_messages", "write_messages"]

FILE = "messages.csv.gz"


def write_messages(df: pd.DataFrame, out_dir: Path) -> Path:
    """Write ``messages.csv.gz`` into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / FILE
    tmp = out_dir / f".{FILE}.part"
    df.to_csv(tmp, index=False, float_format="%.9g", compression="gzip")
    os.replace(tmp, path)  # never a half-written table under the final name
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
    from sigma_des.guard import input_file

    input_file(path, str(path), "live message table (messages.csv.gz)")
    expected = "a gzip-compressed CSV written by `sigma-des live --out`"
    try:
        df = pd.read_csv(path)
    except pd.errors.EmptyDataError:
        raise ConfigError(str(path), f"is empty; expected {expected}") from None
    except (OSError, EOFError, UnicodeDecodeError, pd.errors.ParserError, ValueError) as e:
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise ConfigError(str(path), f"not readable as {expected} ({why})") from None
    need = {"method", "kind", "node", "frame", "t_send", "t_recv"}
    if not need <= set(df.columns):
        raise ConfigError(str(path), f"missing columns {sorted(need - set(df.columns))}")
    if df.empty:
        raise ConfigError(str(path), "has a header but no message rows; expected the "
                          "messages of a live run")
    for col in ("node", "frame", "t_send", "t_recv"):
        if not pd.api.types.is_numeric_dtype(df[col]):
            raise ConfigError(str(path), f"column {col!r} is not numeric")
    return df


def ned(obs: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                           NDArray[np.float64]]:
    """NED position (m), NED velocity (m/s) and Euler angles (rad) of ``(n, 12)`` published
    states (``OBS_FIELDS``: body velocities u, v, w rotated by the ZYX Euler angles;
    altitude up -> down)."""
    u, v, w = obs[:, 0], obs[:, 1], obs[:, 2]
    phi, th, psi = obs[:, 3], obs[:, 4], obs[:, 5]
    cf, sf, ct, st, cp, sp = (np.cos(phi), np.sin(phi), np.cos(th), np.sin(th), np.cos(psi),
                              np.sin(psi))
    vn = ct * cp * u + (sf * st * cp - cf * sp) * v + (cf * st * cp + sf * sp) * w
    ve = ct * sp * u + (sf * st * sp + cf * cp) * v + (cf * st * sp - sf * cp) * w
    vd = -st * u + sf * ct * v + cf * ct * w
    pos = np.stack([obs[:, 9], obs[:, 10], -obs[:, 11]], axis=1)
    return pos, np.stack([vn, ve, vd], axis=1), obs[:, 3:6].copy()


def record_messages(recorder_cls: Any, path: str, res: Any, msgs: pd.DataFrame,
                    kept: dict[str, dict[str, list[Any]]]) -> None:
    """Write the live run to an MCAP file through the recorder API (``sigma_des.record``).

    Triggers are recorded once per node of the receiving host (its receive time),
    states with their NED pose, commands with their values and the host's receive
    time, aligned snapshots and render samples as the server kept them
    (``kept[method]``, see ``LiveServer.kept``).
    """
    sc = res.scenario
    host_of = np.asarray(sc.host_of)
    r = sc.record
    with recorder_cls(path, scenario=to_dict(sc), mode=r.mode, deadband_pos=r.deadband_pos,
                      deadband_vel=r.deadband_vel, deadband_att=r.deadband_att,
                      keyframe_every=r.keyframe_every) as rec:
        for method in res.methods:
            run = rec.run(method, mode="live")
            m = msgs[msgs["method"] == method]
            for r in m[m["kind"] == "trigger"].itertuples():
                for i in np.flatnonzero(host_of == r.host).tolist():
                    run.trigger(frame=int(r.frame), node=i, t_send=float(r.t_send),
                                t_recv=float(r.t_recv))
            k = kept.get(method, {})
            if k.get("obs"):
                pos, vel, att = ned(np.asarray(k["obs"], dtype=np.float64))
                for j, (node, frame, ts, tr) in enumerate(k["states"]):
                    run.state(node=node, frame=frame, t_send=ts, t_recv=tr,
                              pos=tuple(pos[j]), vel=tuple(vel[j]), att=tuple(att[j]))
            got = {(int(r.node), int(r.frame)): float(r.t_recv)
                   for r in m[m["kind"] == "command"].itertuples()}
            for node, tick, ts, values in k.get("commands", []):
                run.command(node=node, frame=tick, t_send=ts,
                            t_recv=got.get((node, tick), float("nan")), values=tuple(values))
            for t, frame, frames, obs in k.get("snapshots", []):
                run.snapshot(t=t, frame=frame, frames=frames, pos=ned(obs)[0])
            for t, aoi in k.get("renders", []):
                run.render(t=t, aoi=aoi)
