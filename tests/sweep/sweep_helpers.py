"""Shared helpers of the sweep tests: a tiny base scenario and a counting task."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from sigma_des import Scenario, load
from sigma_des.sweep import run_task


def tiny_base() -> Scenario:
    """A base scenario that runs in a few ms per method: 1 host, 0.3 s simulated."""
    return load(None, ["hosts=1", "duration=0.3", "warmup=0.1"])


@dataclass
class CountingTask:
    """The default task, counting its calls and failing on chosen (nodes, seed, method).

    Attributes:
        fail_on: configurations that raise ``RuntimeError``.
        interrupt_at: raise ``KeyboardInterrupt`` on this call (1-based; a kill mid-run).
        calls: (nodes, seed, method) of every call, in order.
    """

    fail_on: set[tuple[int, int, str]] = field(default_factory=set)
    interrupt_at: int | None = None
    calls: list[tuple[int, int, str]] = field(default_factory=list)

    def __call__(self, sc: Scenario, method: str) -> Mapping[str, Any]:
        self.calls.append((sc.nodes, sc.seed, method))
        if self.interrupt_at is not None and len(self.calls) == self.interrupt_at:
            raise KeyboardInterrupt
        if (sc.nodes, sc.seed, method) in self.fail_on:
            raise RuntimeError(f"injected failure at nodes={sc.nodes} seed={sc.seed}")
        return run_task(sc, method)
