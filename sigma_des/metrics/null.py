"""The collector that keeps nothing, for runs whose metrics nobody reads.

A learning environment's scenes (``SwarmVec(metrics=False)``) run with it: every report
a run makes is dropped, so a scene skips the metrics' bookkeeping; the run's course is
unchanged because a collector never feeds back into it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.metrics.collector import Collector, CollectorSpec
from sigma_des.metrics.reports import AlignerReport, NetReport, RunReport
from sigma_des.net.cpu import CpuReport

__all__ = ["NullCollector"]


class NullCollector(Collector):
    """A sink that keeps nothing: for runs whose metrics nobody reads (a learning
    env's scenes). Every report is ignored, so the run's course is unchanged (the
    collector never feeds back into it); :meth:`finish` raises.

    Args:
        spec: what a collector knows of the run (kept, unused).
        method: the alignment method's name (kept, unused).
    """

    def __init__(self, spec: CollectorSpec, method: str) -> None:
        self.spec = spec
        self.method = method

    def trigger(self, t: float, k: int, dt: float) -> None:
        pass

    def rate_change(self, t: float, f: float) -> None:
        pass

    def delivered(self, kind: int, subject: int, index: int, t_pub: float, t: float) -> None:
        pass

    def delivered_batch(self, kind: int, latencies: NDArray[np.float64], messages: int,
                        duplicates: int = 0) -> None:
        pass

    def aoi_update(self, t: float, nodes: NDArray[np.int64], gens: NDArray[np.float64]) -> None:
        pass

    def shown(self, t: float, gen: NDArray[np.float64]) -> None:
        pass

    def snapshot(self, t: float) -> None:
        pass

    def render(self, t: float, gen: NDArray[np.float64], frame: NDArray[np.int64],
               obs: NDArray[np.float64], flag: NDArray[np.uint8],
               truth: NDArray[np.float64] | None, f_trig: float, latest: int,
               ref: int) -> None:
        pass

    def finish(self, run: RunReport, aligner: AlignerReport, net: NetReport,
               cpu: CpuReport | None = None) -> dict[str, Any]:
        """No metrics were collected: always raises RuntimeError."""
        raise RuntimeError("this run collected no metrics (metrics=False)")
