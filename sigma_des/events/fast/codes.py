"""The compiled message core's scalar codes: event types, exit codes, message kinds and
the column and counter indices of its small arrays (docs/concepts/engines.md).

The arrays themselves are declared in :mod:`~sigma_des.events.fast.layout`; these are
the named integers that index them and that the handlers exchange. numba folds these
module-level integers into the compiled code as constants, so ``S[INTS][I_DUPS]`` is a
static offset.
"""

from __future__ import annotations

from sigma_des.net.kinds import Kind

# event types
EV_BROKER, EV_CLIENT, EV_DONE = 0, 1, 2
# exit codes of advance()
OK, NEED_START, NEED_ROLLBACK, NEED_FLUSH, NEED_SPACE, DRAW_MISS, BARRIER = 0, 1, 2, 3, 4, 5, 6
# the next event publishes a state Python still owes a re-simulation of (deferred rollbacks)
NEED_RESIM = 7
# a resend's or PUBACK's draws are not in the tables yet (QoS 1 over datagram, streams)
NEED_FILL = 8
#: every exit code by name (one place, so no two parts of the core reuse a number)
EXIT_CODES: dict[str, int] = {
    "OK": OK, "NEED_START": NEED_START, "NEED_ROLLBACK": NEED_ROLLBACK,
    "NEED_FLUSH": NEED_FLUSH, "NEED_SPACE": NEED_SPACE, "DRAW_MISS": DRAW_MISS,
    "BARRIER": BARRIER, "NEED_RESIM": NEED_RESIM, "NEED_FILL": NEED_FILL,
}

# message kinds, as plain ints for numba (declared once, in sigma_des.net.kinds)
K_TRIGGER, K_STATE, K_COMMAND, K_REREQ, K_REPUB = (int(k) for k in Kind)
#: message kinds + 1 (kind 0 is the compute source's key in the draw tables)
N_KINDS = len(Kind) + 1

# queue keys pack (sequence << SLOT_BITS) | event slot into one int64
SLOT_BITS = 24
SLOT_MASK = (1 << SLOT_BITS) - 1
MAX_SLOTS = 1 << SLOT_BITS

# int scalars (S.ints); I_HEAP is unused since the run-merge queue (its scalars are Q_INT's)
I_HEAP, I_EID, I_FREE, I_OUT, I_MSGS, I_HMISS, I_PEND, I_PNODE, I_PA, I_PB, I_NEV, I_ERR = range(12)
I_LAT = 12  # three counters: trigger, state, command latencies buffered
I_LCUR, I_LMISS, I_LCOMP = 15, 16, 17  # Lock-Step barrier mirror: frame, missing, complete
I_DUPS = 18  # duplicate deliveries (Collector.delivered's rule)
I_PFREE = 19  # free rows of the payload pool (S.pool_free's top)
# the truth's newest stepped frame (set by the driver before the loop runs: a rollback's
# first frame is clamped to the ring by it) and the rollbacks deferred in S.def_int
I_LATEST, I_DEFN = 20, 21
# fan-out batches (fanout.py): the element ring's head, tail and used rows; deliveries
# run from batches, batches queued, batches queued again (pending), single deliveries
I_BHEAD, I_BTAIL, I_BUSED, I_BELEM, I_BPUSH, I_BREIN, I_BSING = range(22, 29)
# deliveries of broadcasts the broker fanned out one by one although batching was on (a
# payload, or no room in the element ring: fanout.fits)
I_BNOFIT = 29
I_LEN = 30
# run-merge queue int scalars (S.q_int): pending count, pending minimum's key, arena top,
# runs sealed since the last compaction, heap size, current run and whether there is one
QI_PN, QI_PMINK, QI_ATOP, QI_NRUN, QI_HEAP, QI_CUR, QI_HAS = range(7)
QI_LEN = 7
# run-merge queue float scalars (S.q_float): the pending minimum's time
QF_PMIN = 0
QF_LEN = 1
# float scalars (S.floats)
F_BUSY, F_WORK, F_MAXWAIT, F_PT = range(4)
F_LEN = 4
# int parameters (S.iparams)
Q_N, Q_H, Q_HLC, Q_WARP, Q_THETA, Q_QOS1S, Q_ACK, Q_W, Q_M, Q_LOCK = range(10)
Q_BATCH = 10  # the truth re-simulates deferred rollbacks in a batch (else: Python at once)
# Q_RING: delivered states go straight into the aligner's ring (S.ring_*, the rule of
# align.ring.insert_row); Q_OUT: they are also buffered for Python (S.out_*: the aligner's
# on_states without a ring, or a recording tap)
Q_RING, Q_OUT = 11, 12
Q_FAN = 13  # a broadcast fans out in batches (fanout.py)
Q_CHAN = 14  # a hop's arrival is queued through its channel (channel.py)
Q_LEN = 15
# float parameters (S.fparams)
G_WARMUP, G_END = 0, 1
G_LEN = 2
# node integer rows (S.node)
N_FRAME, N_REQ, N_TARGET, N_BUSY, N_RB, N_CSTAMP = range(6)
N_ROWS = 6
# a deferred rollback (S.def_int): node, first frame to re-simulate (clamped), steps owed
D_NODE, D_FIRST, D_STEPS = range(3)
# a target's rollback draws (S.rb_tag): the target a row holds (-1: none), draws filled
RB_TARGET, RB_ROWS = range(2)
# event int columns (S.ev_int): type, client/receiver, kind, subject, index, aux (HLC c
# or command stamp), frame (of a state, republished state or re-request); attempt of the
# transmission (QoS 1 or stream segment); in a transport event (F2) the type of the event
# it becomes, its action TA_*, its stream sequence number and pending-list links; the
# row of its payload in the pool, + 1 (0: none)
E_TYPE, E_WHO, E_KIND, E_SUBJ, E_INDEX, E_AUX, E_FRAME = range(7)
E_ATT, E_RTYPE, E_TACT, E_SEQ, E_NEXT, E_PREV, E_PAY = range(7, 14)
E_COLS = 14
# event float columns (S.ev_float): t_publish, t_depart, HLC l, generation time (a
# payload, the observation of a state or the row of a command, is a row of S.pool:
# primitives.give_payload)
EF_TPUB, EF_TDEP, EF_L, EF_GEN = range(4)
EF_COLS = 4
#: an application copy's (EV_APP) receipt time at its client, where the latency ends:
#: its departure column, no longer needed once the copy has arrived
EF_TRECV = EF_TDEP
# draw sources: latency and loss uniforms per (link class, direction), broker, compute
LAT_SU, LAT_SD, LAT_HU, LAT_HD = 0, 1, 2, 3
U_OFFSET = 4
SVC_PUB, SVC_DEL, STEP = 8, 9, 10
N_SOURCES = 11

# F2 — transport: event type of a transport event (QoS 1 resend timer, stream retry or
# arrival) and its actions, transport parameters
# (S.tr_params; T_STREAM + link class: a stream with hold-back), float parameters,
# counters and the draining connection (S.tr_ints), stream connection rows (S.conn)
EV_RESEND = 3
TA_RESEND, TA_RETRY, TA_ARRIVE, TA_GONE = range(4)
#: a downlink segment (held behind a gap, or resent) its receiver's network thread has
#: read: when the loop may take it is in its EF_TRECV column (Network.read_held)
TA_READ = 4
T_QOS1D, T_RETRIES, T_DUPALL, T_XROWS, T_STREAM = range(5)
T_QLEN = 6
TF_TIMEOUT, TF_RTO = range(2)
TF_LEN = 2
T_RETX, T_GAVE, T_FKIND, T_FINDEX, T_FATT, T_DRAIN = range(6)
T_ILEN = 6
C_SEQ, C_DELIVER, C_HEAD, C_TAIL, C_LOST = range(5)

# F3 — deployment (docs/concepts/deployment.md): event types of a
# publish whose CPU burst ends (the PUBLISH leaves) and of a received copy handed to the
# application (after its receive burst, or at once with per-host clients), S.cpu_ip, S.cpu_acc
EV_SEND, EV_APP = 4, 5
#: event type of a process's outbox check (``deployment.lock_switch``: publishes whose
#: burst ended while the thread was busy leave when it waits or the switch is due)
EV_LEAVE = 6
#: network thread (``*_net_msg``): a copy it read reaches the loop; a PUBLISH it took leaves
EV_LOOP, EV_NSEND = 7, 8
#: a fan-out batch: a broadcast's deliveries whose arrivals do not decrease (fanout.py)
EV_BATCH = 9
#: a channel's token: a FIFO of events of one kind of hop whose arrivals do not decrease
#: (channel.py)
EV_CHAN = 10
#: event types (rows of S.tally)
EV_TYPES = 11
#: channels (channel.py): deliveries leaving the broker (a hop down), publishes reaching it
#: (a hop up); a channel's scalars (S.ch_int): its ring's head and used rows, its token's
#: slot (-1: none), events run from it, events queued one by one (arrival out of order,
#: ring full), the token's moves into a run of its own after another event fell between
N_CHAN = 2
CH_HEAD, CH_USED, CH_TOKEN, CH_RUN, CH_OOO, CH_FULL, CH_MOVE = range(7)
CH_LEN = 7
#: most publishes of one process waiting in its outbox (beyond: ``ERR_OUTBOX``)
OB_CAP = 4096
# CP_MAXMEM: the most nodes one client hands a message to (room a delivery event
# needs in the latency buffers); CP_SWITCH: lock_switch > 0 (outboxes in use)
CP_APP, CP_BROKER, CP_HOSTS, CP_NSUB, CP_MAXMEM, CP_SWITCH = range(6)
CP_LEN = 6
#: process indices (the spec's ``Cpu.processes`` order): broker, server, host h at 2 + h
P_BROKER, P_SERVER, P_HOST0 = 0, 1, 2
CA_BUSY, CA_WAIT, CA_QUEUED = range(3)
#: columns of a machine's load window (S.cpu_load): growth on (1.0) or off, background
#: cores, end of the current window, CPU seconds arrived in it, the run-queue wait per
#: CPU second it gives (``net.cpu.Machine.load_wait``)
ML_GROW, ML_BG, ML_END, ML_BUSY, ML_Q = range(5)
ML_LEN = 5
