"""The physics truth: the whole swarm's true state per frame, its checkpoints and re-simulation.

By the frame-boundary rule (docs/concepts/model.md, "Physics nodes") the true state of
every node at frame k is known when trigger k is issued, so the swarm is stepped
then, in one vectorised call of the dynamics model. The truth keeps the last
``history_frames`` frames in a ring: each frame's published-state rows (what a
node publishes when it completes that frame), its step ``dt`` and physics time,
and, for BiDES time warp, the state checkpoints a rollback re-simulates from.
A frame enters the fidelity log (:class:`~sigma_des.metrics.fidelity.TrajectoryLog`)
only when it leaves the ring and can no longer be rolled back.

When the run is over (:meth:`SwarmTruth.release`, called by the engine's run) the frames
still in the ring enter the log and the rings are let go: they are the run's largest
arrays (164 MB at N = 1 000 once filled), and a finished run lingers as cyclic garbage
until a full collection, so a process running one run after another (``compare``, a
sweep, a benchmark) would otherwise keep every earlier run's rings resident and fault
fresh pages for each new one (docs/concepts/engines.md).

A rollback re-simulates at once (:meth:`SwarmTruth.rollback`, the per-message
engine's path) or, for the compiled core, later and in a batch: the core counts the
owed compute steps (arithmetic) and keeps the pending rollbacks in its own arrays
(:mod:`sigma_des.events.fast.warp`), and :meth:`SwarmTruth.flush_rollbacks`
re-simulates them. The rows of different aircraft are independent, so one step call
per frame over every pending aircraft gives each row the very bits its own
re-simulation gives it (the dynamics' ``step_frames`` marks a model whose rows do not
depend on the batch; others, and a model whose ``defer_rollbacks`` is False, re-simulate
at once). With such a model a rollback whose re-simulation would change no bit (the
frames were stepped with that very command row) skips its physics
(:mod:`sigma_des.events.held`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.filled import filled
from sigma_des.core.models import OBS_FIELDS, DynamicsModel
from sigma_des.core.pages import small_pages
from sigma_des.events.held import HeldCommands
from sigma_des.metrics.fidelity import TrajectoryLog

__all__ = ["NO_LOG", "FrameTrack", "NoLog", "SwarmTruth"]

#: Columns of the published state.
OBS_COLUMNS = len(OBS_FIELDS)


class FrameTrack:
    """Every frame's true positions, in frame order: the log of a live host's truth.

    A host holds some of the swarm's nodes; the runner joins the hosts' logs by frame
    and samples them at the fidelity log rate as the DES's
    :class:`~sigma_des.metrics.fidelity.TrajectoryLog` does. The truth steps every frame
    from 0 and logs each as it leaves its ring, so the ``k``-th sample is frame ``k``.

    Args:
        columns: nodes of each sample.
    """

    def __init__(self, columns: int) -> None:
        self.times: list[float] = []
        self.pos: list[NDArray[np.float64]] = []
        self._columns = columns

    def add(self, t: float, pos: NDArray[np.float64]) -> None:
        """The frame leaving the ring: physics time ``t``, positions ``pos`` (copied)."""
        self.times.append(t)
        self.pos.append(pos.copy())

    def arrays(self) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
        """``(frames (T,), times (T,), positions (T, columns, 3))``."""
        pos = np.stack(self.pos) if self.pos else np.zeros((0, self._columns, 3))
        return (np.arange(len(self.times), dtype=np.int64),
                np.array(self.times, dtype=np.float64), pos)


class NoLog:
    """Where frames leaving the ring go when nobody reads them: nowhere (a run
    without metrics, e.g. a learning env's scene)."""

    def add(self, t: float, pos: NDArray[np.float64]) -> None:
        """Forget the frame leaving the ring."""


#: The shared :class:`NoLog` (it holds nothing).
NO_LOG = NoLog()


class SwarmTruth:
    """The true swarm, or a subset of its nodes, frame by frame.

    Args:
        dynamics: the vectorised dynamics model.
        n: number of nodes of the swarm.
        history_frames: length of the frame ring.
        log_rate: rate (Hz of physics time) of the fidelity log.
        checkpoints: keep state checkpoints (only time-warp rollbacks read them).
        nodes: the node ids served, ascending (None: all ``n``); rows are indexed by
            position in it, the dynamics keyed by the id (a live host's nodes).
        log: where frames leaving the ring go (None: the fidelity log at ``log_rate``;
            a live host passes a :class:`FrameTrack`; :data:`NO_LOG`: nowhere).

    Attributes:
        nodes: the node id of every row.
        state: ``(m, state_dim)`` true state at the latest frame (``m`` nodes served);
            with checkpoints and a model that steps into a given array, a view of the
            latest frame's checkpoint slot (a copy once released).
        ckpt: state after frame ``f`` at ``f % H`` (empty without checkpoints).
        obs_hist: published rows of frame ``f`` at ``f % H``.
        slot_frame: the frame held at each ring slot (-1: none yet).
        frame_dt: step ``dt`` of frame ``f`` at ``f % H``.
        latest: the newest frame stepped (-1 before the first).
        rollbacks: number of time-warp rollbacks.
        resim_steps: frames re-simulated by them (node compute steps).
        stepped_rows: the command rows the nodes' frames were stepped with (None without
            batched steps): a rollback that would re-step frames with the very row they
            were stepped with, from the same checkpoint, is skipped (the same bits).
        resim_skipped: rollbacks whose physics was skipped so (still counted above).
    """

    def __init__(
        self, dynamics: DynamicsModel, n: int, history_frames: int, log_rate: float,
        checkpoints: bool, nodes: NDArray[np.int64] | None = None,
        log: TrajectoryLog | FrameTrack | NoLog | None = None,
    ) -> None:
        small_pages()  # the rings below are written a frame at a time (core/pages.py)
        H = self.H = history_frames
        self.dyn = dynamics
        initial = dynamics.initial_state(n)
        if nodes is None:
            self.nodes = np.arange(n, dtype=np.int64)
            self.initial = initial
        else:
            self.nodes = np.asarray(nodes, dtype=np.int64)
            self.initial = initial[self.nodes].copy()
        n = self.nodes.size
        self.state = self.initial.copy()
        # uninitialised (a slot is read only once written, see _checkpoint): a fresh
        # zeroed array of this size faults its pages in one by one at first touch,
        # ~10x the cost of np.empty's (huge-page) memory on Linux
        self.ckpt = np.empty(((H if checkpoints else 0),) + self.state.shape)
        # likewise uninitialised: a slot is read only once its frame was stepped (every
        # reader checks ``slot_frame``, and a node publishes only frames already issued);
        # a NaN fill touched every page at set-up (49 MB at N = 1000: 10-130 ms)
        self.obs_hist = np.empty((H, n, OBS_COLUMNS))
        self.slot_frame = filled(H, -1, np.int64)
        self.frame_dt = np.zeros(H)
        self.latest = -1
        self.phys_t = 0.0
        self.phys_hist = np.zeros(H)
        self.traj: TrajectoryLog | FrameTrack | NoLog = (
            TrajectoryLog(log_rate, dynamics.observe(self.initial)[:, 9:12]) if log is None
            else log)
        self.rollbacks = 0
        self.resim_steps = 0
        self.batched = (getattr(dynamics, "step_frames", None) is not None and checkpoints
                        and getattr(dynamics, "defer_rollbacks", True))
        # the rows each node's frames were stepped with: a rollback that would re-step
        # them with the same row from the same checkpoint is skipped (events/held.py)
        self.stepped_rows = HeldCommands(n, dynamics.command_dim) if self.batched else None
        self.resim_skipped = 0
        # models that write a step / an observation into a given array (the same bits):
        # the frame is stepped into its ring slots, no per-frame temporaries
        self._step_into = getattr(dynamics, "step_into", None)
        self._observe_into = getattr(dynamics, "observe_into", None)
        # a model that re-simulates a rollback straight into the ring (one call)
        self._resimulate_into = getattr(dynamics, "resimulate_into", None)
        self.released = False

    def step_frame(
        self, k: int, dt: float, cmd: NDArray[np.float64], pending: NDArray[np.float64] | None
    ) -> None:
        """Step the swarm to frame ``k`` with the command rows ``cmd``.

        Args:
            k: the frame (the trigger being issued).
            dt: its step (s).
            cmd: ``(n, command_dim)`` commands in force at frame ``k``.
            pending: the state of frame ``k`` already stepped outside with the very
                same ``(state, cmd, dt, k)`` (batched physics of ``sigma_des.env``);
                None: step here.

        Raises:
            RuntimeError: the truth was released (the run is over).
        """
        if self.released:
            raise RuntimeError("the run is over: its truth was released")
        slot = k % self.H
        if self.slot_frame[slot] >= 0 and self.traj is not NO_LOG:
            self.traj.add(float(self.phys_hist[slot]), self.obs_hist[slot, :, 9:12])
        self.frame_dt[slot] = dt
        self.phys_t += dt
        self.phys_hist[slot] = self.phys_t
        keep = self.ckpt.shape[0] > 0
        if pending is not None:
            self.state = pending
            if keep:
                self.ckpt[slot] = pending
        elif keep and self._step_into is not None:
            # stepped straight into its checkpoint slot: the state is that slot (a view)
            out = self.ckpt[slot]
            self._step_into(self.state, cmd, dt, k, self.nodes, out)
            self.state = out
        else:
            self.state = self.dyn.step(self.state, cmd, dt, k, self.nodes)
            if keep:
                self.ckpt[slot] = self.state
        if self._observe_into is not None:
            self._observe_into(self.state, self.obs_hist[slot])
        else:
            self.obs_hist[slot] = self.dyn.observe(self.state)
        if self.stepped_rows is not None:
            self.stepped_rows.stepped(k, cmd)
        self.slot_frame[slot] = k
        self.latest = k

    def held(self, frame: int) -> bool:
        """True if the ring still holds ``frame``."""
        return frame >= 0 and self.slot_frame[frame % self.H] == frame

    def positions(self, frame: int) -> NDArray[np.float64] | None:
        """True ``(n, 3)`` positions (x, y, h) of ``frame``, None if not held."""
        if not self.held(frame):
            return None
        return self.obs_hist[frame % self.H, :, 9:12]

    def rollback(self, i: int, c: int, current: int, row: NDArray[np.float64]) -> int:
        """Re-simulate node ``i`` from frame ``c`` with command ``row`` (time warp).

        Frames older than the ring are not re-simulated (``c`` is clamped to the
        oldest frame whose previous checkpoint is held).

        Args:
            i: the node's row (its position in :attr:`nodes`).
            c: the frame the command applies from.
            current: the node's own frame (the one it computes or last computed).
            row: the command row.

        Returns:
            The compute steps the node's next job owes: ``current - c + 1`` (≥ 0).
        """
        c = self.first_resim(c)
        held = self.stepped_rows
        if held is None or c > self.latest:
            self._resimulate_one(i, c, row)
        else:
            one = (np.array([i]), np.array([c]), np.asarray(row, dtype=np.float64)[None, :])
            if held.redundant(*one)[0]:
                self.resim_skipped += 1  # the ring already holds what it would write
            else:
                self._resimulate_one(i, c, row)
                held.resimulated(*one)
        steps = max(0, current - c + 1)
        self.rollbacks += 1
        self.resim_steps += steps
        return steps

    def _resimulate_one(self, i: int, c: int, row: NDArray[np.float64]) -> None:
        """:meth:`rollback`'s physics: node ``i`` from frame ``c`` (clamped) with ``row``."""
        H = self.H
        latest = self.latest
        prev = self._checkpoint(i, c)
        if self._resimulate_into is not None and c <= latest:
            self._resimulate_into(prev, row, self.frame_dt, c, latest, i, self.ckpt,
                                  self.obs_hist, self.state)
            return
        step_frames = getattr(self.dyn, "step_frames", None)
        if step_frames is not None and c <= latest:
            # the same row steps, compiled in one call (identical to the loop below);
            # observed from its result, the rows just written to the ring
            slots = np.arange(c, latest + 1) % H
            states = step_frames(prev, row, self.frame_dt[slots], c, int(self.nodes[i]))
            self.ckpt[slots, i] = states
            self.obs_hist[slots, i] = self.dyn.observe(states)
            self.state[i] = states[-1]
            return
        s = prev[None, :].copy()
        cmd = row[None, :]
        node = self.nodes[i : i + 1]
        for f in range(c, latest + 1):
            slot = f % H
            s = self.dyn.step(s, cmd, float(self.frame_dt[slot]), f, node)
            self.ckpt[slot, i] = s[0]
        if c <= latest:
            # one observe call for all re-simulated frames (rows are independent)
            slots = np.arange(c, latest + 1) % H
            self.obs_hist[slots, i] = self.dyn.observe(self.ckpt[slots, i])
        self.state[i] = s[0]

    def _checkpoint(self, i: int, c: int) -> NDArray[np.float64]:
        """Node ``i``'s state before frame ``c``: its checkpoint of frame ``c - 1``.

        The initial state for ``c = 0``; a ring slot never written reads as zeros (the
        ring's former ``np.zeros`` fill; unreachable: a rollback's ``c`` is held).
        """
        if c == 0:
            return self.initial[i]
        slot = (c - 1) % self.H
        if self.slot_frame[slot] < 0:
            return np.zeros(self.state.shape[1])
        return self.ckpt[slot, i]

    def first_resim(self, c: int) -> int:
        """Frame ``c`` clamped to the oldest frame a rollback re-simulates (the oldest
        whose previous checkpoint the ring holds)."""
        return max(c, max(0, self.latest - self.H + 2))

    def flush_rollbacks(
        self, nodes: NDArray[np.int64], first: NDArray[np.int64], rows: NDArray[np.float64],
        steps: NDArray[np.int64],
    ) -> NDArray[np.int64]:
        """Re-simulate rollbacks deferred by the compiled core: one step call per frame.

        Each is :meth:`rollback` ``(nodes[k], first[k], ·, rows[k])`` with its physics done
        here, in a batch (see the module doc): the compiled core counted the owed steps
        and clamped the first frames (:meth:`first_resim`) when it deferred them, in
        arrival order, one per node.

        Args:
            nodes: the nodes' rows, one rollback each, in arrival order.
            first: the first frame each re-simulates (clamped; at most :attr:`latest`).
            rows: the command row each re-simulates with.
            steps: the compute steps each rollback owed (counted in :attr:`resim_steps`).

        Returns:
            The nodes rolled back, by first frame (stable: in arrival order on ties):
            re-simulated, or skipped where the ring already holds the rows their
            re-simulation would write (:mod:`sigma_des.events.held`).

        Raises:
            ValueError: a node twice, a first frame outside the ring or past the latest
                frame, or a dynamics model without batched steps.
        """
        if nodes.size == 0:
            return self.nodes[:0]
        lo = self.first_resim(0)
        if (not self.batched or np.unique(nodes).size != nodes.size
                or int(first.min()) < lo or int(first.max()) > self.latest):
            raise ValueError("deferred rollbacks: one per node, first frames in "
                             f"[{lo}, {self.latest}], batched dynamics")
        self.rollbacks += int(nodes.size)
        self.resim_steps += int(steps.sum())
        order = np.argsort(first, kind="stable")  # by first frame (stable)
        nodes, first, rows = nodes[order], first[order], rows[order]
        held = self.stepped_rows
        assert held is not None  # batched
        todo = ~held.redundant(nodes, first, rows)  # the others: the ring holds their rows
        self.resim_skipped += int(nodes.size - np.count_nonzero(todo))
        if todo.any():
            self._resimulate(nodes[todo], first[todo], rows[todo])
            held.resimulated(nodes[todo], first[todo], rows[todo])
        return nodes

    def _resimulate(
        self, nodes: NDArray[np.int64], first: NDArray[np.int64], rows: NDArray[np.float64]
    ) -> None:
        """:meth:`flush_rollbacks`' physics: one step call per frame (``first`` ascending)."""
        H, latest = self.H, self.latest
        cur = self._checkpoints(nodes, first)
        ids = self.nodes[nodes]  # the dynamics is keyed by node id (rows: by position)
        m = 0
        for f in range(int(first[0]), latest + 1):
            while m < nodes.size and first[m] <= f:
                m += 1
            slot = f % H
            cur[:m] = self.dyn.step(cur[:m], rows[:m], float(self.frame_dt[slot]), f, ids[:m])
            self.ckpt[slot, nodes[:m]] = cur[:m]
            # observed frame by frame (rows are independent: the same bits as one call
            # over every re-simulated row, without gathering them again from the ring,
            # a few MB of fresh temporaries in the first second's rollback burst)
            self.obs_hist[slot, nodes[:m]] = self.dyn.observe(cur[:m])
        self.state[nodes] = cur

    def _checkpoints(
        self, nodes: NDArray[np.int64], first: NDArray[np.int64]
    ) -> NDArray[np.float64]:
        """:meth:`_checkpoint` of each ``(nodes[k], first[k])``, as rows of a new array."""
        cur = np.zeros((nodes.size, self.state.shape[1]))
        at0 = first == 0
        cur[at0] = self.initial[nodes[at0]]
        slots = (first - 1) % self.H
        held = ~at0 & (self.slot_frame[slots] >= 0)  # else zeros, as _checkpoint
        cur[held] = self.ckpt[slots[held], nodes[held]]
        return cur

    def trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """True positions logged at the fidelity log rate (Hz of physics time), so far."""
        return self.trajectory_log().arrays()

    def trajectory_log(self) -> TrajectoryLog:
        """The log :meth:`trajectory` reads, the ring's frames logged first: for readers
        that take it a block of samples at a time (:meth:`TrajectoryLog.rows`)."""
        log = self.traj
        if not isinstance(log, TrajectoryLog):
            raise TypeError("this truth keeps no fidelity log (a FrameTrack logs every "
                            "frame; NO_LOG none)")
        self._log_ring()
        return log

    def _log_ring(self) -> None:
        """Log the frames the ring holds (none once released: release() logged them)."""
        if self.released or self.traj is NO_LOG:
            return
        first = max(0, self.latest - self.H + 1)
        for f in range(first, self.latest + 1):
            slot = f % self.H
            self.traj.add(float(self.phys_hist[slot]), self.obs_hist[slot, :, 9:12])

    def release(self) -> None:
        """The run is over: log the frames the ring still holds, then drop the rings.

        :meth:`trajectory` returns the same arrays after as before; no frame is held
        any more (:meth:`held` is False, :meth:`positions` None) and the truth cannot
        step or roll back again. The state of the latest frame (:attr:`state`) stays.
        """
        if self.released:
            return
        self._log_ring()
        self.released = True
        if self.state.base is not None and np.may_share_memory(self.state, self.ckpt):
            self.state = self.state.copy()  # a view of its checkpoint slot: keep the row only
        self.slot_frame[:] = -1  # in place: the compiled core holds this array
        self.ckpt = np.empty((0, *self.ckpt.shape[1:]))
        self.obs_hist = np.empty((0, *self.obs_hist.shape[1:]))
