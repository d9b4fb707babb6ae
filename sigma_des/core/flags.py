"""How a shown state relates to the snapshot's frame: the flags every layer shares.

The alignment methods (:mod:`sigma_des.events.align`) set one flag per node of the
snapshot they show; the metrics (:mod:`sigma_des.metrics.collector`) count them
(docs/concepts/methods.md and "Metrics"). They sit on the ground floor so
that both import them downward.
"""

from __future__ import annotations

__all__ = ["EXACT", "EXTRAPOLATED", "FILLED", "MISSING"]

#: The node's state at exactly the aligned frame.
EXACT = 0
#: A hole filled from neighbouring frames (interpolated, copied or held).
FILLED = 1
#: Node excluded for lag; its state extrapolated to the aligned frame.
EXTRAPOLATED = 2
#: Nothing usable to show.
MISSING = 3
