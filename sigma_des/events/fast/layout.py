"""The compiled message core's state, declared once by name (docs/concepts/engines.md).

All state of the core is one tuple ``S`` of numpy arrays, built from the
declaration :data:`FIELDS`: each :class:`Field` gives the array's name, dtype and
shape (as names of dimensions resolved at allocation) and how it starts. The
position of every field is generated from the declaration (:data:`INDEX` and one
constant per field, its name in capitals: ``S[HEAP_T]``); numba folds these
module-level integers into the compiled code, so an access is a static offset.
A plain tuple, not a named one: numba types a plain tuple of arrays on each call
in C (~4 us for this state), a named tuple in Python (~20 us), and the driver
calls the loop thousands of times per run.

Small arrays of scalars (counters, parameters, per-node rows, event columns) are
indexed by the named integer constants of :mod:`~sigma_des.events.fast.codes`; numba
folds module-level integers into the compiled code as constants.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.events.fast.codes import (
    CH_LEN,
    CP_LEN,
    E_COLS,
    EF_COLS,
    EV_TYPES,
    F_LEN,
    G_LEN,
    I_LEN,
    ML_LEN,
    N_CHAN,
    N_KINDS,
    N_ROWS,
    N_SOURCES,
    OB_CAP,
    Q_LEN,
    QF_LEN,
    QI_LEN,
    T_ILEN,
    T_QLEN,
    TF_LEN,
)
from sigma_des.events.fast.declare import Field, Plan, build, plan, shape_of, swap
from sigma_des.net.cpu import RESERVATIONS

__all__ = ["FIELDS", "INDEX", "Field", "allocate", "replaced", "shape_of"]



_f, _i = np.float64, np.int64

#: The state of the compiled core, in order. Dimensions: ``cap`` event slots,
#: ``arena`` run-arena rows, ``n`` nodes, ``clients`` = n + 1 (the server is
#: client n), ``links`` = hosts + 1 access links, ``hosts``, ``cores``, ``tables``
#: draw-table rows, ``H`` history frames, ``W`` observation width, ``M`` command
#: width, ``out``/``lat`` delivery buffer capacities, ``ring_n``/``ring_k`` the
#: aligner's ring buffers,
#: ``slow`` slow-fault windows, ``seen_n``/``seen_h`` duplicate table,
#: ``links_1`` = links + 1, and the link and clock tables' ``ge_slots``, ``deg``,
#: ``drops``, ``ntp_j``; ``seen_k`` the duplicate table's kind rows (every kind under
#: QoS 1 over datagram), ``ack_tables``/``x_tables``/``x_rows`` the PUBACK and resend
#: draw tables, ``pool`` payload rows of ``pay_w`` = max(W, M) floats, ``rb_t`` rollback
#: targets of ``rb_j`` draws each.
FIELDS: tuple[Field, ...] = (
    Field("heap_t", _f, ("cap",), 0.0, "heap of run heads: times"),
    Field("heap_k", _i, ("cap",), 0.0, "heap of run heads: keys (sequence << SLOT_BITS | slot)"),
    Field("ev_int", np.int32, ("cap", E_COLS), 0.0,
          "event slots: int columns E_* (int32: every value is checked, EV_INT_MAX)"),
    Field("ev_float", _f, ("cap", EF_COLS), 0.0, "event slots: float columns EF_*"),
    Field("free", _i, ("cap",), None, "free list of event slots"),
    Field("ints", _i, (I_LEN,), 0.0, "int scalars I_*"),
    Field("floats", _f, (F_LEN,), 0.0, "float scalars F_*"),
    Field("iparams", _i, (Q_LEN,), None, "int parameters Q_*"),
    Field("fparams", _f, (G_LEN,), None, "float parameters G_*"),
    Field("link_busy", _f, (2, "links"), 0.0, "access links (down, up): busy until"),
    Field("link_count", _i, (2, 2, "links"), 0.0, "(down, up) x (bytes, packets) in window"),
    Field("link_spb", _f, (2, "links"), None, "(down, up): seconds per byte"),
    Field("link_of", _i, ("clients",), None, "access link of each client"),
    Field("draw_map", _i, (N_SOURCES, N_KINDS), None, "(source, kind) -> table row, -1 const"),
    Field("draw_const", _f, (N_SOURCES,), None, "constant value of a source"),
    Field("draw_val", _f, ("tables", "H", "clients"), None, "draw tables: values"),
    Field("draw_tag", _i, ("tables", "H"), None, "draw tables: index held by each row"),
    Field("p_loss", _f, (2,), None, "loss probability per link class (host, server)"),
    Field("wire_bytes", _i, (N_KINDS,), None, "bytes on the wire per message kind"),
    Field("node", _i, (N_ROWS, "n"), None, "node rows N_*"),
    Field("host_of", _i, ("n",), None, "host of each node"),
    Field("crash", _f, ("n",), None, "crash time of each node (inf: never)"),
    Field("slow_ptr", _i, ("clients",), None, "slow-fault windows of node i: rows ptr[i]:ptr[i+1]"),
    Field("slow", _f, ("slow", 3), None, "slow-fault windows (start, end, factor)"),
    Field("cores", _f, ("hosts", "cores"), 0.0, "host cores: busy until"),
    Field("hlc_l", _f, ("n",), -np.inf, "node HLC: l"),
    Field("hlc_c", _i, ("n",), 0.0, "node HLC: c"),
    Field("clock_off", _f, ("n",), None, "node clock offset"),
    Field("clock_drift", _f, ("n",), None, "node clock drift (fraction)"),
    Field("slot_frame", _i, ("H",), None, "engine's physics ring: frame of each slot"),
    Field("obs_hist", _f, ("H", "n", "W"), None, "engine's physics ring: observations"),
    Field("cmd", _f, ("n", "M"), None, "engine's current command of each node"),
    Field("out_int", _i, ("out", 3), 0.0, "state deliveries: subject, frame, HLC c"),
    Field("out_float", _f, ("out", "out_w"), 0.0, "state deliveries: t, gen, HLC l, obs"),
    Field("lat_buf", _f, (3, "lat"), 0.0, "latencies of trigger, state, command deliveries"),
    Field("last_int", _i, ("n", 2), None, "last published state: frame, HLC c"),
    Field("last_float", _f, ("n", "last_w"), 0.0, "last published state: gen, HLC l, obs"),
    Field("ls_mirror", _i, (2, "n"), 0.0, "Lock-Step barrier mirror: got, live"),
    Field("seen", _i, ("seen_k", "seen_n", "seen_h"), -1.0,
          "duplicate rule: newest index per (kind row, subject, index % seen_h)"),
    # the run-merge event queue (sigma_des.events.fast.queue)
    Field("heap_r", _i, ("cap",), 0.0, "heap of run heads: run ids"),
    Field("pend_t", _f, ("cap",), 0.0, "pending events (creation order): times"),
    Field("pend_k", _i, ("cap",), 0.0, "pending events: keys"),
    Field("run_t", _f, ("arena",), 0.0, "run arena: times (each run sorted)"),
    Field("run_k", _i, ("arena",), 0.0, "run arena: keys"),
    Field("run_pos", _i, ("cap",), 0.0, "run table: arena position of each run's head"),
    Field("run_end", _i, ("cap",), 0.0, "run table: arena end of each run"),
    Field("run_fwd", _i, ("cap",), 0.0, "compaction scratch: new id of each run"),
    Field("bounds", _i, ("arena",), 0.0, "sealing scratch: boundaries of sorted stretches"),
    Field("q_int", _i, (QI_LEN,), 0.0, "run-merge queue int scalars QI_*"),
    Field("q_float", _f, (QF_LEN,), 0.0, "run-merge queue float scalars QF_*"),
    # F1, link-level features (Gilbert–Elliott loss, degrade and drop faults, NTP clocks):
    # ``ge_slots`` chain slots, ``deg`` degrade windows, ``drops`` dropped keys,
    # ``ntp_j`` NTP sync instants (each table bounded by the run's end + a margin)
    Field("link_dyn", _i, (4,), None, "link features on: GE host, GE server, degrade, drops"),
    Field("ge_par", _f, (2, 3), None, "Gilbert-Elliott per link class: slot, loss_good, loss_bad"),
    Field("ge_bad", np.uint8, (2, "links", "ge_slots"), None, "GE chain (down, up): bad per slot"),
    Field("deg_ptr", _i, ("links_1",), None, "degrade windows of link k: rows ptr[k]:ptr[k+1]"),
    Field("deg", _f, ("deg", 4), None, "degrade windows in fault order (start, end, delay, loss)"),
    Field("drops", _i, ("drops", 3), None, "drop faults' (kind, subject, index), sorted"),
    Field("ntp_period", _f, (1,), None, "NTP period (0: no NTP)"),
    Field("ntp_res", _f, ("n", "ntp_j"), None, "NTP residual of node i after sync j (j >= 1)"),
    # P (per-frame Python path): batched time-warp re-simulation
    Field("resim_pend", _i, ("clients",), 0.0,
          "node's rollback re-simulation still owed by Python; [n]: any node's"),
    # F2 — transport: QoS 1 over datagram (PUBACK hops, resend timers, redelivery)
    Field("tr_params", _i, (T_QLEN,), None, "transport int parameters T_*"),
    Field("tr_fparams", _f, (TF_LEN,), None, "transport float parameters TF_*"),
    Field("tr_ints", _i, (T_ILEN,), 0.0, "transport counters and the draw-fill request"),
    Field("ack_map", _i, (N_SOURCES, N_KINDS), None, "PUBACK draws, attempt 0: -> table"),
    Field("ack_val", _f, ("ack_tables", "H", "clients"), None, "PUBACK draws: values"),
    Field("ack_tag", _i, ("ack_tables", "H"), None, "PUBACK draws: index held by each row"),
    Field("x_map", _i, (N_SOURCES, 2 * N_KINDS), None,
          "draws of attempts >= 1: (source, kind [+ N_KINDS: PUBACK]) -> table, -1 const"),
    Field("x_const", _f, (N_SOURCES,), None, "constant value of a source (attempts >= 1)"),
    Field("x_first", _i, (N_KINDS,), None, "first attempt table of each kind (-1: none)"),
    Field("x_val", _f, ("x_tables", "x_rows", "clients"), None, "attempt draws: values"),
    Field("x_tag", _i, ("x_tables", "x_rows"), None,
          "attempt draws: key index * (max_retries + 1) + attempt held by each row"),
    Field("conn", _i, (5, 2, "clients"), None,
          "stream connections (down, up) per client: next seq, next to deliver, pending "
          "list, segments awaiting a resend"),
    Field("tr_floats", _f, (1,), 0.0, "time of the arrival whose in-order deliveries drain"),
    # F3 — deployment: processes on machines' cores (``procs`` = hosts + 2, ``machines``,
    # ``cpu_cores``) and per-host MQTT clients (``clients_1`` = clients + 1)
    Field("cpu_ip", _i, (CP_LEN,), None, "deployment int parameters CP_*"),
    Field("cpu_proc", _i, ("clients",), None, "process of each client's bursts (-1: none)"),
    Field("cpu_dem", _f, ("clients",), None, "CPU demand of each client's bursts (s)"),
    Field("cpu_mach", _i, ("procs",), None, "machine of each process"),
    Field("cpu_scale", _f, ("procs",), None, "background slow-down of each process"),
    Field("cpu_free", _f, ("procs",), -np.inf, "process thread: free again at"),
    Field("cpu_iv", _f, ("machines", "cpu_cores", RESERVATIONS + 1, 2), 0.0,
          "machine cores' reservations [start, end), in start order (+1: room to insert)"),
    Field("cpu_niv", _i, ("machines", "cpu_cores"), 0, "reservations each core holds"),
    Field("cpu_acc", _f, ("procs", 3), 0.0,
          "process CPU seconds, longest wait and run-queue wait in window"),
    Field("cpu_runq", _f, ("procs",), None, "run-queue wait floor per CPU second, per process"),
    Field("cpu_grow", _f, ("procs",), None, "1: the process's bursts wait its machine's queue"),
    Field("cpu_load", _f, ("machines", ML_LEN), None, "each machine's load window ML_*"),
    Field("cpu_bursts", _i, ("procs",), 0.0, "bursts arriving in the window, per process"),
    Field("cl_of", _i, ("clients",), None, "MQTT client of each node (the server's: itself)"),
    Field("bcast", _i, ("clients",), None, "a broadcast's subscribers (first CP_NSUB)"),
    Field("mem_ptr", _i, ("clients_1",), None, "nodes of client c: mem[ptr[c]:ptr[c+1]]"),
    Field("mem", _i, ("n",), None, "nodes of each client, in node order"),
    Field("cpu_wake", _f, ("procs",), None, "CPU a burst finding its thread idle costs more"),
    Field("cpu_side", _f, ("procs",), None, "a wake-up's CPU on the process's other thread"),
    Field("cpu_switch", _f, ("procs",), None, "lock_switch of each process (0: no outbox)"),
    Field("cpu_ob", _i, ("procs", OB_CAP), 0, "outbox: slots waiting to leave, a ring"),
    Field("cpu_obq", _i, ("procs", 2), 0, "outbox: ring head and count"),
    Field("cpu_obt", _f, ("procs",), 0.0, "outbox: when its first message leaves at the latest"),
    Field("cpu_inb", _f, ("procs",), -np.inf, "receipts: when the open batch is read"),
    Field("cpu_net", _f, ("procs", 2), None, "network thread: CPU a message, more a wake-up"),
    Field("cpu_nfree", _f, ("procs",), -np.inf, "network thread: free again at"),
    # memory: the payloads of the event slots that carry one (a state's
    # observation, a command's row; a trigger or re-request carries none), ``pool`` rows
    # of ``pay_w`` = max(W, M) floats; a slot names its row in E_PAY (+ 1)
    Field("pool", _f, ("pool", "pay_w"), 0.0, "payload pool: one payload a row"),
    Field("pool_free", np.int32, ("pool",), None, "free list of payload rows (top: I_PFREE)"),
    # speed: rollbacks resolved in the loop (``rb_t`` targets of ``rb_j`` draws)
    Field("def_int", _i, ("n", 3), 0.0, "deferred rollbacks in arrival order: D_* (I_DEFN)"),
    Field("def_row", _f, ("n", "M"), 0.0, "deferred rollbacks: the command row re-simulated"),
    Field("rb_val", _f, ("rb_t", "rb_j", "n"), None,
          "rollback draws (ROLLBACK_DRAW, node, target, j) of target row target % rb_t"),
    Field("rb_tag", _i, ("rb_t", 2), None, "rollback draws: target held, draws filled RB_*"),
    # speed: the aligner's ring buffers (align.ring.RingBuffers, shared in
    # place: ``ring_n`` nodes x ``ring_k`` slots; 1 x 1 and unused unless Q_RING)
    Field("ring_frame", _i, ("ring_n", "ring_k"), None, "aligner's ring: frame of each slot"),
    Field("ring_gen", _f, ("ring_n", "ring_k"), None, "aligner's ring: generation times"),
    Field("ring_obs", _f, ("ring_n", "ring_k", "W"), None, "aligner's ring: the states"),
    Field("ring_latest", _i, ("ring_n",), None, "aligner's ring: newest frame of each node"),
    # fan-out batches (fanout.py): a ring of ``bat`` elements, one per delivery
    Field("bat_t", _f, ("bat",), 0.0, "fan-out elements: arrival times"),
    Field("bat_k", _i, ("bat",), 0.0, "fan-out elements: sequence << SLOT_BITS (-1: delivered)"),
    Field("bat_w", _i, ("bat",), 0.0, "fan-out elements: subscriber"),
    # channels (channel.py): a ring of ``bat`` elements each
    Field("ch_t", _f, (N_CHAN, "bat"), 0.0, "channel elements: arrival times"),
    Field("ch_k", _i, (N_CHAN, "bat"), 0.0, "channel elements: keys (sequence, slot)"),
    Field("ch_int", _i, (N_CHAN, CH_LEN), 0.0, "channel scalars CH_*"),
    Field("tally", _i, (2, EV_TYPES, N_KINDS), 0.0,
          "events run (one by one, from batches) by type and kind (tally.py)"),
)

#: Position of each field in the state tuple, generated from :data:`FIELDS`.
INDEX: dict[str, int] = {f.name: i for i, f in enumerate(FIELDS)}
# The positions by name, for the compiled code (numba folds these globals into constants,
# so ``S[HEAP_T]`` is a static offset; a test checks them against the declaration).
HEAP_T = INDEX["heap_t"]
HEAP_K = INDEX["heap_k"]
EV_INT = INDEX["ev_int"]
EV_FLOAT = INDEX["ev_float"]
FREE = INDEX["free"]
INTS = INDEX["ints"]
FLOATS = INDEX["floats"]
IPARAMS = INDEX["iparams"]
FPARAMS = INDEX["fparams"]
LINK_BUSY = INDEX["link_busy"]
LINK_COUNT = INDEX["link_count"]
LINK_SPB = INDEX["link_spb"]
LINK_OF = INDEX["link_of"]
DRAW_MAP = INDEX["draw_map"]
DRAW_CONST = INDEX["draw_const"]
DRAW_VAL = INDEX["draw_val"]
DRAW_TAG = INDEX["draw_tag"]
P_LOSS = INDEX["p_loss"]
WIRE_BYTES = INDEX["wire_bytes"]
NODE = INDEX["node"]
HOST_OF = INDEX["host_of"]
CRASH = INDEX["crash"]
SLOW_PTR = INDEX["slow_ptr"]
SLOW = INDEX["slow"]
CORES = INDEX["cores"]
HLC_L = INDEX["hlc_l"]
HLC_C = INDEX["hlc_c"]
CLOCK_OFF = INDEX["clock_off"]
CLOCK_DRIFT = INDEX["clock_drift"]
SLOT_FRAME = INDEX["slot_frame"]
OBS_HIST = INDEX["obs_hist"]
CMD = INDEX["cmd"]
OUT_INT = INDEX["out_int"]
OUT_FLOAT = INDEX["out_float"]
LAT_BUF = INDEX["lat_buf"]
LAST_INT = INDEX["last_int"]
LAST_FLOAT = INDEX["last_float"]
LS_MIRROR = INDEX["ls_mirror"]
SEEN = INDEX["seen"]
HEAP_R = INDEX["heap_r"]
PEND_T = INDEX["pend_t"]
PEND_K = INDEX["pend_k"]
RUN_T = INDEX["run_t"]
RUN_K = INDEX["run_k"]
RUN_POS = INDEX["run_pos"]
RUN_END = INDEX["run_end"]
RUN_FWD = INDEX["run_fwd"]
BOUNDS = INDEX["bounds"]
Q_INT = INDEX["q_int"]
Q_FLOAT = INDEX["q_float"]
# F1, link-level features
LINK_DYN = INDEX["link_dyn"]
GE_PAR = INDEX["ge_par"]
GE_BAD = INDEX["ge_bad"]
DEG_PTR, DEG = INDEX["deg_ptr"], INDEX["deg"]
DROPS = INDEX["drops"]
NTP_PERIOD, NTP_RES = INDEX["ntp_period"], INDEX["ntp_res"]
#: ``S.ints[I_ERR]`` when a send time or clock reading lies beyond the link or clock
#: tables (the run's end + :data:`~sigma_des.events.fast.support.TABLE_MARGIN`)
ERR_HORIZON = 2
#: ``S.ints[I_ERR]`` when a value the loop makes (an HLC counter, a stream sequence
#: number) does not fit the event table's int32 columns
ERR_RANGE = 3
#: ``S.ints[I_ERR]`` when more than :data:`OB_CAP` publishes of one process wait in
#: its outbox
ERR_OUTBOX = 4
#: Largest value an event slot's int column holds (``ev_int`` is int32: 56 B a slot,
#: not 104; a saturated broker's backlog holds 10^6 slots). Values that could exceed it
#: are checked where they enter: frame and tick indices and stamps at the driver's
#: publishes, HLC counters and stream sequence numbers in the loop (``ERR_RANGE``).
EV_INT_MAX = (1 << 31) - 1
RESIM_PEND = INDEX["resim_pend"]
TR_PARAMS = INDEX["tr_params"]
TR_FPARAMS = INDEX["tr_fparams"]
TR_INTS = INDEX["tr_ints"]
ACK_MAP, ACK_VAL = INDEX["ack_map"], INDEX["ack_val"]
ACK_TAG = INDEX["ack_tag"]
X_MAP = INDEX["x_map"]
X_CONST, X_FIRST = INDEX["x_const"], INDEX["x_first"]
X_VAL = INDEX["x_val"]
X_TAG = INDEX["x_tag"]
CONN = INDEX["conn"]
TR_FLOATS = INDEX["tr_floats"]
CPU_IP = INDEX["cpu_ip"]
CPU_PROC = INDEX["cpu_proc"]
CPU_DEM = INDEX["cpu_dem"]
CPU_MACH = INDEX["cpu_mach"]
CPU_SCALE = INDEX["cpu_scale"]
CPU_FREE = INDEX["cpu_free"]
CPU_IV = INDEX["cpu_iv"]
CPU_NIV = INDEX["cpu_niv"]
CPU_ACC = INDEX["cpu_acc"]
CPU_BURSTS = INDEX["cpu_bursts"]
CL_OF = INDEX["cl_of"]
BCAST = INDEX["bcast"]
MEM_PTR, MEM = INDEX["mem_ptr"], INDEX["mem"]
CPU_WAKE, CPU_SIDE = INDEX["cpu_wake"], INDEX["cpu_side"]
CPU_RUNQ, CPU_LOAD, CPU_GROW = INDEX["cpu_runq"], INDEX["cpu_load"], INDEX["cpu_grow"]
CPU_SWITCH = INDEX["cpu_switch"]
CPU_OB, CPU_OBQ = INDEX["cpu_ob"], INDEX["cpu_obq"]
CPU_OBT, CPU_INB = INDEX["cpu_obt"], INDEX["cpu_inb"]
CPU_NET, CPU_NFREE = INDEX["cpu_net"], INDEX["cpu_nfree"]
POOL, POOL_FREE = INDEX["pool"], INDEX["pool_free"]
DEF_INT, DEF_ROW = INDEX["def_int"], INDEX["def_row"]
RB_VAL, RB_TAG = INDEX["rb_val"], INDEX["rb_tag"]
RING_FRAME = INDEX["ring_frame"]
RING_GEN = INDEX["ring_gen"]
RING_OBS = INDEX["ring_obs"]
RING_LATEST = INDEX["ring_latest"]
BAT_T, BAT_K, BAT_W = INDEX["bat_t"], INDEX["bat_k"], INDEX["bat_w"]
CH_T, CH_K, CH_INT = INDEX["ch_t"], INDEX["ch_k"], INDEX["ch_int"]
TALLY = INDEX["tally"]


def allocate(
    dims: Mapping[str, int], given: Mapping[str, NDArray[Any]],
    spare: Mapping[str, NDArray[Any]] | None = None,
) -> tuple[NDArray[Any], ...]:
    """The core's state tuple (:func:`~sigma_des.events.fast.declare.build` of
    :data:`FIELDS`): ``given`` arrays checked, the others made from their fill, or
    refilled from ``spare`` (a retired state's arrays; the declaration's
    :func:`~sigma_des.events.fast.declare.plan` kept per set of dimensions: the scenes
    of a learning env and their episodes share it)."""
    key = tuple(dims.items())
    p = _PLANS.get(key)
    if p is None:
        if len(_PLANS) >= 64:
            _PLANS.clear()
        p = _PLANS[key] = plan(FIELDS, dims)
    return build(p, dims, given, spare)


_PLANS: dict[tuple[tuple[str, int], ...], Plan] = {}


def replaced(
    S: tuple[NDArray[Any], ...], new: Mapping[str, NDArray[Any]]
) -> tuple[NDArray[Any], ...]:
    """The state ``S`` with the arrays of the fields named in ``new`` replaced."""
    return swap(S, INDEX, new)
