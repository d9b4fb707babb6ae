"""State latency split into its stages, live against the DES, per validation cell.

``python -m sigma_lab.studies.validation.stages VALIDATION_DIR [CELL...]`` reads each
live run's per-message log (``live/<cell>/messages.csv.gz``) and runs the calibrated
DES of the same cell (``cal/``, prepared by :func:`sigma_des.calibrate.target.prepare`
as the suite prepares it) on the per-message engine with every state delivery to the
server recorded (publish, broker departure, receipt). Per cell and method it prints,
for the states published in the metrics window (ms):

* ``lat``: mean state latency (publish -> the server's receipt);
* ``first``: the latency of each frame's first-published state (the part a state
  pays with nothing of its own frame ahead of it);
* ``q1..q4``: mean latency by quarter of the publish order within the frame (how
  the wait grows behind the frame's earlier states);
* ``send``/``recv``: mean spread of a frame's publish and receipt times;
* DES only, ``up``/``down``: publish -> the broker's departure, and on to the receipt.

Live logs have no broker stamps, so live is split by order and spread, not by hop.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sigma_lab.studies.validation.grid import full_plan, hosts_for

METHODS = ("none", "lockstep", "hlc", "bides")
CELLS = ("n10-node", "cal-r1", "n30-node", "n10-bundle", "cal-bundle", "n30-bundle",
         "n60-bundle")


def frame_stats(s: pd.DataFrame) -> dict[str, float]:
    """The figures of states with ``frame``, ``t_send``, ``t_recv`` (s) (module doc)."""
    s = s.assign(lat=(s.t_recv - s.t_send) * 1e3)
    g = s.groupby("frame")
    rank = g.t_send.rank(method="first") - 1.0
    size = g.t_send.transform("size")
    quarter = np.minimum((4.0 * rank / size).astype(int), 3)
    first = s.loc[rank == 0.0, "lat"]
    out = {"lat": float(s.lat.mean()), "first": float(first.mean()),
           "send": float((g.t_send.max() - g.t_send.min()).mean() * 1e3),
           "recv": float((g.t_recv.max() - g.t_recv.min()).mean() * 1e3)}
    by = s.groupby(quarter).lat.mean()
    out.update({f"q{q + 1}": float(by.get(q, np.nan)) for q in range(4)})
    return out


def live_stats(run: Path, method: str, warmup: float, duration: float) -> dict[str, float]:
    """:func:`frame_stats` of one live run's states of ``method``."""
    df = pd.read_csv(run / "messages.csv.gz")
    s = df[(df.method == method) & (df.kind == "state") & (df.t_send >= warmup)
           & (df.t_send < duration)]
    return frame_stats(s)


@contextmanager
def recorded(rows: list[tuple[float, ...]]) -> Iterator[None]:
    """While open, every delivery to the server of a recorded per-message run appends
    ``(node, frame, t_pub, t_sent, t_recv)`` to ``rows``."""
    from sigma_des.events.engine import MethodRun

    orig = MethodRun.deliver_recorded

    def rec(self: Any, m: Any) -> None:
        if m.client == self.server:
            rows.append((m.subject, m.index, m.t_pub, m.t_sent, m.t_recv))
        orig(self, m)

    MethodRun.deliver_recorded = rec  # type: ignore[method-assign]
    try:
        yield
    finally:
        MethodRun.deliver_recorded = orig  # type: ignore[method-assign]


def des_stats(val: Path, cell: str, method: str, duration: float, warmup: float
              ) -> dict[str, float]:
    """:func:`frame_stats` (and ``up``/``down``) of the calibrated DES of ``cell``."""
    from sigma_des.calibrate.target import prepare
    from sigma_des.config import load
    from sigma_des.events.cohort import execute
    from sigma_des.events.tap import Tap
    from sigma_des.factory import make_behaviour, make_dynamics

    cal = load(str(val / "cal" / "calibrated.toml"))
    rep = json.loads((val / "cal" / "calibrated.json").read_text())
    sizes = {c.name: c.nodes for c in full_plan(METHODS, cal_bundle=True).cells}
    n = sizes[cell] if cell in sizes else int(cell.split("-")[0][1:])
    sc = prepare(cal, rep, [f"nodes={n}", f"hosts={hosts_for(n)}", f"duration={duration}",
                            f"warmup={warmup}", 'engine="events"'],
                 bundle=cell.endswith("bundle"))
    rows: list[tuple[float, ...]] = []
    with recorded(rows):
        execute(sc.run_spec(), method, lambda: make_dynamics(sc), lambda: make_behaviour(sc),
                None, Tap)
    s = pd.DataFrame(rows, columns=["node", "frame", "t_send", "t_sent", "t_recv"])
    s = s[(s.t_send >= warmup) & (s.t_send < duration)].drop_duplicates(["node", "frame"])
    out = frame_stats(s)
    out["up"] = float((s.t_sent - s.t_send).mean() * 1e3)
    out["down"] = float((s.t_recv - s.t_sent).mean() * 1e3)
    return out


def _fmt(tag: str, cell: str, m: str, st: dict[str, float]) -> str:
    keys = ["lat", "first", "q1", "q2", "q3", "q4", "send", "recv", "up", "down"]
    return f"{tag:4s} {cell:11s} {m:8s} " + " ".join(
        f"{k} {st[k]:5.2f}" for k in keys if k in st)


def main(argv: list[str] | None = None) -> int:
    """Print the decomposition (module doc)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("val", type=Path, help="a live_vs_des.py output folder")
    p.add_argument("cells", nargs="*", default=list(CELLS))
    p.add_argument("--methods", default="none,lockstep")
    p.add_argument("--duration", type=float, default=4.0)
    p.add_argument("--warmup", type=float, default=1.0)
    a = p.parse_args(argv)
    for cell in a.cells:
        for m in a.methods.split(","):
            print(_fmt("live", cell, m, live_stats(a.val / "live" / cell, m, a.warmup,
                                                   a.duration)))
            print(_fmt("des", cell, m, des_stats(a.val, cell, m, a.duration, a.warmup)),
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
