"""Memory budget of a run: estimate it before running, refuse what cannot fit.

The estimate adds up the arrays that grow with the scenario (the per-frame
history ring, BiDES's ring buffers and checkpoints, the per-render-tick samples,
the latency series and the fidelity trajectories) for one method run, times the
runs held at once. It is an estimate of the large arrays, not of every object;
its purpose is to refuse a run that would exhaust memory (``history_frames =
1e9``, a day at 10 kHz with a million nodes) before it starts, with the figure.
"""

from __future__ import annotations

import os
from pathlib import Path

from sigma_des.config import Scenario
from sigma_des.errors import ConfigError

__all__ = ["available_bytes", "check_memory", "estimate_bytes"]

_F8 = 8  # a float64 array element
_PYFLOAT = 32  # a float in a Python list: the object plus the list's pointer
_OBS = 12  # observation columns per node and frame
_STATE_MAX = 32  # an upper bound of any dynamics model's state columns
_PER_NODE = 4096  # per-node bookkeeping of both engines (lists, rows, draw caches)


def estimate_bytes(sc: Scenario, concurrent: int = 1) -> int:
    """Bytes the large arrays of ``concurrent`` simultaneous method runs of ``sc`` take.

    Args:
        sc: the scenario.
        concurrent: method runs held in memory at once (``compare --jobs``).

    Returns:
        The estimate (bytes): the sum of :func:`estimate_terms`.
    """
    return sum(estimate_terms(sc, concurrent).values())


def estimate_terms(sc: Scenario, concurrent: int = 1) -> dict[str, int]:
    """The terms of :func:`estimate_bytes`, each named by the keys that size it."""
    n = sc.nodes
    window = sc.duration - sc.warmup
    warp = "bides" in sc.methods and sc.bides.time_warp
    history = sc.history_frames * n * (_OBS + (_STATE_MAX if warp else 0)) * _F8
    ring = sc.bides.ring_size * n * (_OBS + 2) * _F8 if "bides" in sc.methods else 0
    samples = int(window * sc.f_render) * n * 2 * _F8  # AoI and position error per tick
    cmd_rate = sc.f_align / sc.commands.every if sc.commands.enabled else 0.0
    latencies = int(window * (2 * sc.f_trig + cmd_rate)) * n * _PYFLOAT
    trajectory = 0
    if sc.fidelity.enabled:
        trajectory = (int(sc.duration * sc.fidelity.log_rate) + 1) * n * 3 * _F8
    return {  # the trajectory once more: the ideal run, shared by all methods
        f"history_frames {sc.history_frames} × nodes {n}": concurrent * history,
        f"bides.ring_size {sc.bides.ring_size} × nodes {n}": concurrent * ring,
        f"duration {sc.duration:g} s × f_render {sc.f_render:g} Hz × nodes {n}":
            concurrent * samples,
        f"duration {sc.duration:g} s × f_trig {sc.f_trig:g} Hz × nodes {n}":
            concurrent * latencies,
        f"fidelity.log_rate {sc.fidelity.log_rate:g} Hz × duration {sc.duration:g} s × "
        f"nodes {n}": (concurrent + 1) * trajectory,
        f"nodes {n}": concurrent * n * _PER_NODE,
    }


def available_bytes() -> int | None:
    """Memory available to a new process now (``MemAvailable``), or None if unknown."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (OSError, ValueError, AttributeError):
        return None


def _gib(b: float) -> str:
    return f"{b / 2**30:.3g} GiB"


def check_memory(sc: Scenario, concurrent: int = 1, force: bool = False) -> int:
    """Refuse a run whose estimate exceeds the available memory.

    Args:
        sc: the scenario.
        concurrent: method runs held at once.
        force: skip the refusal (the estimate is still returned).

    Returns:
        The estimate (bytes).

    Raises:
        ConfigError: (key ``memory``) the estimate exceeds the available memory.
    """
    terms = estimate_terms(sc, concurrent)
    need = sum(terms.values())
    have = available_bytes()
    if not force and have is not None and need > have:
        cause = max(terms, key=lambda k: terms[k])
        raise ConfigError(
            "memory",
            f"this run needs about {_gib(need)}, most of it for {cause} "
            f"({_gib(terms[cause])}, × {concurrent} run(s) at once), but {_gib(have)} is "
            "available; lower one of those keys or --jobs, or pass --force",
        )
    return need
