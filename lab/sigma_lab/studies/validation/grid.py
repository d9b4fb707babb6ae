"""The validation grid: which live runs, on which hosts, and how long the whole takes.

A :class:`Cell` is one live invocation (every method of :attr:`Plan.methods` in
turn on one set of host processes) and the DES prediction of it. The plan:

* ``cal-r1`` — the calibration run (N = :attr:`Plan.cal_nodes`, per-node messages);
  ``cal-r2``, ``cal-r3`` — the same setting again (the live noise floor), run later
  in the grid so that they also see the machine's drift;
* ``n<N>-node`` / ``n<N>-bundle`` for N in :attr:`Plan.nodes` — held out;
* ``loss5-<mode>`` (5 % Bernoulli loss on every host link) and ``lat5-<mode>``
  (+5 ms on every host link, both directions) at N = :attr:`Plan.extra_nodes`;
* with :attr:`Plan.cell_repeats` = k > 1 every held-out cell runs k times, the copies
  named ``<cell>-c2`` … ``<cell>-c<k>`` and run in a second (third…) pass over the
  held-out grid: the live range of each cell, for the issue's rule "where live does
  not reproduce itself, the DES inside the range of the live repeats".

Host counts follow :func:`hosts_for` (``max(2, ceil(N / 25))``: 2 hosts up to
N = 50, then one more per 25 nodes; at least 2 so that a trigger's fan-out, and
with it the broker's per-delivery time, can be measured).
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, field, replace

from sigma_des.errors import ConfigError

__all__ = ["Cell", "MODES", "Plan", "full_plan", "hosts_for", "quick_plan"]

#: Message modes: one PUBLISH per node state, or a host's states of one turn bundled.
MODES = ("node", "bundle")
#: Extra scenario keys of each impairment (live and DES alike; the DES's +5 ms is
#: added to the calibrated latency samples instead, see ``runs.shift_host_link``).
LOSS_P = 0.05
EXTRA_LATENCY_S = 0.005
#: The live shim's per-hop latency of the base scenario (``net.host_link.latency``).
BASE_HOP_S = 0.00025


def hosts_for(nodes: int) -> int:
    """The host count of an N-node cell: ``max(2, ceil(N / 25))``."""
    if nodes < 1:
        raise ConfigError("nodes", f"must be >= 1, got {nodes}")
    return max(2, math.ceil(nodes / 25))


@dataclass(frozen=True)
class Cell:
    """One live setting and its DES prediction.

    Attributes:
        name: unique name (``n30-bundle``, ``loss5-node``, ``cal-r2``…).
        nodes: N.
        mode: ``node`` (one PUBLISH per state) or ``bundle`` (live ``--bundle``; DES
            ``deployment.clients = "host"``, ``deployment.bundle = true``).
        impairment: ``""``, ``loss5`` or ``lat5``.
        repeat: 1, 2, 3… for the calibration setting; 0 for a held-out cell.
        copy: 1, 2… for the runs of one held-out cell (1 for the calibration setting).
        cal_extra: a further calibration run of a campaign (``cal-bundle``: the
            calibration setting with bundled messages), neither held out nor a repeat.
    """

    name: str
    nodes: int
    mode: str = "node"
    impairment: str = ""
    repeat: int = 0
    copy: int = 1
    cal_extra: bool = False

    @property
    def base(self) -> str:
        """The held-out cell this run is a copy of (its own name for the first copy)."""
        return self.name if self.copy == 1 else self.name.rsplit("-c", 1)[0]

    @property
    def hosts(self) -> int:
        """Host processes (:func:`hosts_for`)."""
        return hosts_for(self.nodes)

    @property
    def held_out(self) -> bool:
        """True unless this is a calibration run (a repeat or a campaign's extra)."""
        return self.repeat == 0 and not self.cal_extra

    def live_sets(self) -> list[str]:
        """The live scenario's own keys (``key=value``), without duration and warmup."""
        sets = [f"nodes={self.nodes}", f"hosts={self.hosts}"]
        if self.impairment == "loss5":
            sets.append(f"net.host_link.loss.p={LOSS_P}")
        if self.impairment == "lat5":
            sets.append(f"net.host_link.latency.value={BASE_HOP_S + EXTRA_LATENCY_S}")
        return sets

    def des_sets(self) -> list[str]:
        """The keys the DES prediction changes on the calibrated scenario (the message
        mode and an added latency are :func:`sigma_des.calibrate.target.prepare`'s
        options)."""
        sets = [f"nodes={self.nodes}", f"hosts={self.hosts}"]
        if self.impairment == "loss5":
            sets.append(f"net.host_link.loss.p={LOSS_P}")
        return sets


@dataclass(frozen=True)
class Plan:
    """Everything the suite runs.

    Attributes:
        methods: methods of every cell.
        duration: seconds of each live run and DES run (per method).
        warmup: seconds before the metrics window.
        cal_nodes: N of the calibration setting.
        nodes: N of the held-out grid.
        extra_nodes: N of the loss and latency cells.
        repeats: runs of the calibration setting, all calibrated on (the most typical
            one first, the campaign's primary run:
            :func:`~sigma_lab.studies.validation.scoring.central`).
        cell_repeats: runs of each held-out cell (copies in later passes over the grid).
        cal_bundle: also bundled calibration runs of ``cal_bundle_nodes`` nodes
            (``cal-bundle`` right after ``cal-r1``, ``cal-bundle-r2`` right after
            ``cal-r2`` with two repeats or more), calibrated on with the repeats: a
            campaign (``sigma-des calibrate RUN RUN RUN ...``) whose bundled hop
            factor is matched on the bundled runs' mean. Every scored cell differs from
            them in size.
        cal_bundle_nodes: N of the bundled calibration runs (0: ``cal_nodes``). Away
            from the per-node calibration's N: there the per-node match already fits the
            bundled run's CPU, and a factor matched there understates how live's bundled
            excess grows with N.
        knee_nodes: the DES's finer N grid for its knee prediction.
        knee_live: sizes above the held-out grid (increasing) at which live runs once
            more per mode, in order, while some method still holds at the largest size
            live ran: live's own knee, where the held-out grid ends before it. These
            runs enter the knee table only, not the held-out shares.
        cells: the cells (built from the fields above).
        retry_loaded: times a live cell that ran under load runs again (0..3): its
            loaded run is set aside and the cell run anew, at once or, for a cell kept
            from an earlier invocation, when the suite resumes.
        knee_tiebreak: further live runs (0..3) of a held-out size on live's knee grid
            whose runs disagree about holding (``sigma-des capacity``'s predicate, some
            method): named as further copies (``n60-node-c3``), they enter the cell's
            live mean like its other copies.
    """

    methods: tuple[str, ...]
    duration: float
    warmup: float
    cal_nodes: int
    nodes: tuple[int, ...]
    extra_nodes: int
    repeats: int = 3
    knee_nodes: tuple[int, ...] = ()
    knee_live: tuple[int, ...] = ()
    cells: tuple[Cell, ...] = field(default=())
    cell_repeats: int = 1
    cal_bundle: bool = False
    retry_loaded: int = 1
    cal_bundle_nodes: int = 0
    knee_tiebreak: int = 0

    def __post_init__(self) -> None:
        if not 0 <= self.warmup < self.duration:
            raise ConfigError("--duration", f"must exceed the warmup ({self.warmup} s), "
                              f"got {self.duration}")
        if self.repeats < 1:
            raise ConfigError("--repeats", f"must be >= 1, got {self.repeats}")
        if not 1 <= self.cell_repeats <= 5:
            raise ConfigError("--cell-repeats", f"must be in 1..5, got {self.cell_repeats}")
        if self.cal_bundle_nodes < 0:
            raise ConfigError("cal_bundle_nodes", f"must be >= 0 (0: the calibration "
                              f"setting's N), got {self.cal_bundle_nodes}")
        if not 0 <= self.retry_loaded <= 3:
            raise ConfigError("--retry-loaded", f"must be in 0..3, got {self.retry_loaded}")
        if not 0 <= self.knee_tiebreak <= 3:
            raise ConfigError("--knee-tiebreak", f"must be in 0..3, got {self.knee_tiebreak}")
        top = max(self.nodes, default=0)
        if list(self.knee_live) != sorted(set(self.knee_live)) or any(
                n <= top for n in self.knee_live):
            raise ConfigError("knee_live", f"must increase and exceed the held-out grid's "
                              f"largest N ({top}), got {list(self.knee_live)}")
        if not self.cells:
            object.__setattr__(self, "cells", self._build())

    def _build(self) -> tuple[Cell, ...]:
        held = [Cell(f"n{n}-{m}", n, m) for m in MODES for n in self.nodes]
        held += [Cell(f"{imp}-{m}", self.extra_nodes, m, imp) for imp in ("loss5", "lat5")
                 for m in MODES]
        held += [replace(c, name=f"{c.name}-c{k}", copy=k)
                 for k in range(2, self.cell_repeats + 1) for c in held]
        reps = [Cell(f"cal-r{r}", self.cal_nodes, "node", "", r)
                for r in range(1, self.repeats + 1)]
        # the repeats spread over the grid: first, in the middle, last; with cal_bundle
        # a bundled run right after the first and (two repeats or more) the second
        nb = self.cal_bundle_nodes or self.cal_nodes
        bundled = [Cell("cal-bundle", nb, "bundle", cal_extra=True),
                   Cell("cal-bundle-r2", nb, "bundle", cal_extra=True)]
        bundled = bundled[:min(2, len(reps))] if self.cal_bundle else []
        out = [reps[0], *bundled[:1]]
        cuts = [round(len(held) * k / max(1, len(reps) - 1)) for k in range(1, len(reps))]
        start = 0
        for r, (rep, cut) in enumerate(zip(reps[1:], cuts, strict=True)):
            out += held[start:cut] + [rep, *bundled[1:2 if r == 0 else 1]]
            start = cut
        return tuple(out + held[start:])

    def select(self, patterns: str | None) -> Plan:
        """The plan with only the cells matching ``patterns`` (comma-separated globs,
        e.g. ``n30-*,loss5-node``); the calibration runs ``cal-r1`` (and the bundled
        ``cal-bundle*``) are always kept.

        Raises:
            ConfigError: (``--grid``) a pattern that matches no cell.
        """
        if not patterns:
            return self
        pats = [p.strip() for p in patterns.split(",") if p.strip()]
        names = [c.name for c in self.cells]
        for p in pats:
            if not fnmatch.filter(names, p):
                raise ConfigError("--grid", f"{p!r} matches no cell; cells: {', '.join(names)}")
        keep = tuple(c for c in self.cells
                     if c.repeat == 1 or c.cal_extra
                     or any(fnmatch.fnmatch(c.name, p) for p in pats))
        return replace(self, cells=keep)

    def knee_live_cells(self, mode: str) -> tuple[Cell, ...]:
        """The live runs of :attr:`knee_live` in ``mode`` (the suite runs them in order
        while some method still holds; named like the DES's knee cells)."""
        return tuple(Cell(f"knee-n{n}-{mode}", n, mode) for n in self.knee_live)

    def tiebreak_cells(self, cell: Cell) -> tuple[Cell, ...]:
        """The further copies of held-out ``cell`` a knee tie-break may run
        (:attr:`knee_tiebreak`), numbered after its :attr:`cell_repeats` copies."""
        first = self.cell_repeats + 1
        return tuple(replace(cell, name=f"{cell.base}-c{k}", copy=k)
                     for k in range(first, first + self.knee_tiebreak))

    def knee_cells(self) -> tuple[Cell, ...]:
        """DES-only cells of the knee grid (both modes)."""
        return tuple(Cell(f"knee-n{n}-{m}", n, m) for m in MODES for n in self.knee_nodes)

    def estimate(self, live_overhead: float = 4.0, method_overhead: float = 1.6,
                 des_base: float = 1.0, des_per_node: float = 0.05, cal_s: float = 40.0
                 ) -> float:
        """Expected wall seconds of the whole plan on an idle 2-core machine.

        Live: ``live_overhead`` (broker, host processes) per cell plus, per method,
        the run and ``method_overhead`` (ready, 1 s idle window, stop) — measured on
        this machine: 22 s for N = 30, 4 methods, 3 s runs. DES: per method run
        ``des_base + des_per_node * N`` seconds per 4 simulated seconds (the
        per-message engine, which runs every CPU-stage scenario until the compiled
        core has it: 3.9 s at N = 60, 8.9 s at N = 150, measured); the calibration
        with its in-sample check ``cal_s``. Every live knee run counted (at most).
        """
        m = len(self.methods)
        runs = len(self.cells) + len(MODES) * (len(self.knee_live)
                                               + len(self.nodes) * self.knee_tiebreak)
        live = runs * (live_overhead + m * (self.duration + method_overhead))
        keys = {(c.nodes, c.mode, c.impairment) for c in self.cells}
        keys |= {(c.nodes, c.mode, "") for c in self.knee_cells()}
        des = sum(des_base + des_per_node * n for n, _, _ in keys) * m * self.duration / 4.0
        return live + cal_s + des


def full_plan(methods: tuple[str, ...], duration: float = 4.0, warmup: float = 1.0,
              cell_repeats: int = 2, cal_bundle: bool = False, retry_loaded: int = 1,
              knee_tiebreak: int = 1) -> Plan:
    """The issue's grid: N in {10, 30, 60, 100}, both modes, loss/latency at N = 30,
    each held-out cell ``cell_repeats`` times, the calibration setting 3 times at
    N = 20 (with ``cal_bundle`` also twice bundled at N = 40); the DES's knee grid 10,
    20, … 60, 80, 100, 120, 150, 180; live's knee runs at 120, 150 and 180 while a
    method still holds at the last size run; one more live run of a held-out size
    whose runs disagree about holding. Both grids reach 180, a fifth past 150, so that
    a knee at 150 on one side and none by 150 on the other is decided within the
    knee's ±25 % rather than left as an unknown beyond the grid."""
    return Plan(methods, duration, warmup, cal_nodes=20, nodes=(10, 30, 60, 100),
                extra_nodes=30, repeats=3,
                knee_nodes=(10, 20, 30, 40, 50, 60, 80, 100, 120, 150, 180),
                knee_live=(120, 150, 180),
                cell_repeats=cell_repeats, cal_bundle=cal_bundle, retry_loaded=retry_loaded,
                cal_bundle_nodes=40, knee_tiebreak=knee_tiebreak)


def quick_plan(methods: tuple[str, ...], duration: float = 1.5, warmup: float = 0.5,
               cell_repeats: int = 1, cal_bundle: bool = False, retry_loaded: int = 0,
               knee_tiebreak: int = 0) -> Plan:
    """A smoke run: calibration at N = 4 twice, N = 6 both modes, no impairments, no
    retries of loaded runs."""
    plan = Plan(methods, duration, warmup, cal_nodes=4, nodes=(6,), extra_nodes=6,
                repeats=2, knee_nodes=(4, 6, 8), cell_repeats=cell_repeats,
                cal_bundle=cal_bundle, retry_loaded=retry_loaded, knee_tiebreak=knee_tiebreak)
    return plan.select("cal-r*,n6-*")
