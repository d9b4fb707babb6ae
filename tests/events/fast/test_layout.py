"""The compiled core's state layout is generated from its one declaration."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sigma_des.events.engine import MethodRun
from sigma_des.events.fast import codes as CO
from sigma_des.events.fast import layout as L
from sigma_des.events.fast.driver import CompiledCore
from sigma_des.factory import make_behaviour, make_dynamics
from sigma_des.net.cpu import RESERVATIONS
from tests.conftest import tiny

DIMS = {
    "cap": 5, "arena": 6, "n": 3, "clients": 4, "links": 3, "hosts": 2, "cores": 4, "tables": 2,
    "H": 8, "W": 12, "M": 3, "pay_w": 12, "pool": 4, "out": 6, "out_w": 15, "lat": 7, "last_w": 14,
    "slow": 1, "seen_k": 2, "seen_n": 1, "seen_h": 1,
    "links_1": 4, "ge_slots": 5, "deg": 1, "drops": 1, "ntp_j": 2,
    "ack_tables": 1, "x_tables": 1, "x_rows": 1,
    "procs": 4, "machines": 1, "cpu_cores": 2, "clients_1": 5, "rb_t": 2, "rb_j": 3,
    "ring_n": 3, "ring_k": 4, "bat": 6,
}


def _given() -> dict[str, np.ndarray]:
    return {
        f.name: np.zeros(L.shape_of(f, DIMS), dtype=f.dtype)
        for f in L.FIELDS
        if f.fill is None
    }


def test_positions_are_generated_from_the_declaration() -> None:
    names = [f.name for f in L.FIELDS]
    # 39 + 11 queue + 8 link + 1 resim + 13 transport + 26 deployment + 2 payload pool
    # + 4 rollbacks in the loop + 4 the aligner's ring + 3 fan-out elements
    # + 3 channels + 1 tally
    assert len(set(names)) == len(names) == 115
    assert L.INDEX == {name: i for i, name in enumerate(names)}
    # one module constant per field, its name in capitals, for the compiled code
    assert [getattr(L, name.upper()) for name in names] == list(range(115))
    assert (L.HEAP_T, L.FREE, L.SEEN) == (0, 4, 38)
    assert L.RESIM_PEND == 58  # appended by issue 15's per-frame Python path


def test_allocate_makes_every_declared_array() -> None:
    S = L.allocate(DIMS, _given())
    for f in L.FIELDS:
        a = S[L.INDEX[f.name]]
        assert a.dtype == f.dtype and a.flags.c_contiguous, f.name
        assert a.shape == L.shape_of(f, DIMS), f.name
    assert S[L.EV_FLOAT].shape == (5, 4) and S[L.POOL].shape == (4, 12)
    assert S[L.LINK_COUNT].shape == (2, 2, 3)
    assert S[L.HLC_L].tolist() == [-np.inf] * 3
    assert (S[L.SEEN] == -1).all() and (S[L.EV_INT] == 0).all()


def test_replaced_swaps_named_arrays_only() -> None:
    S = L.allocate(DIMS, _given())
    new = np.zeros(10)
    T = L.replaced(S, {"heap_t": new})
    assert T[L.HEAP_T] is new and T[L.HEAP_K] is S[L.HEAP_K] and len(T) == len(S)


def test_given_arrays_are_shared_not_copied() -> None:
    given = _given()
    S = L.allocate(DIMS, given)
    assert S[L.CMD] is given["cmd"] and S[L.OBS_HIST] is given["obs_hist"]


@pytest.mark.parametrize(
    ("name", "array", "match"),
    [
        ("cmd", np.zeros((3, 4)), r"'cmd': float64\(3, 4\) given, float64\(3, 3\)"),
        ("node", np.zeros((6, 3)), r"'node': float64\(6, 3\) given, int64\(6, 3\)"),
        ("obs_hist", np.zeros((8, 12, 3)).transpose(0, 2, 1), "C-contiguous"),
    ],
)
def test_a_given_array_unlike_its_declaration_is_refused(
    name: str, array: np.ndarray, match: str
) -> None:
    given = _given()
    given[name] = array
    with pytest.raises(ValueError, match=match):
        L.allocate(DIMS, given)


def test_missing_or_unexpected_arrays_are_refused() -> None:
    given = _given()
    del given["slow"]
    with pytest.raises(ValueError, match="'slow': no array given"):
        L.allocate(DIMS, given)
    given = _given()
    given["heap_t"] = np.zeros(5)
    with pytest.raises(ValueError, match=r"fields with a fill: \['heap_t'\]"):
        L.allocate(DIMS, given)


def test_a_run_state_follows_the_declaration() -> None:
    sc = replace(tiny(**{"commands.enabled": True}), engine="cohort")
    run = MethodRun(sc.run_spec(), "bides", make_dynamics(sc), make_behaviour(sc), compiled=True)
    core = run.core
    assert isinstance(core, CompiledCore)
    S = core.S
    assert S[L.NODE].shape == (CO.N_ROWS, 3) and S[L.CLOCK_OFF].shape == (3,)
    assert S[L.LINK_OF].shape == (4,) and S[L.CORES].shape == (2, 4)
    # the engine's physics ring and commands are the core's, in place
    truth = run.truth
    assert S[L.OBS_HIST] is truth.obs_hist and S[L.SLOT_FRAME] is truth.slot_frame
    assert S[L.CMD] is run.nodes.cmd
    q = S[L.IPARAMS]
    assert q[CO.Q_N] == 3 and q[CO.Q_WARP] == 1 and q[CO.Q_LOCK] == 0
    assert q[CO.Q_FAN] == 1  # the tiny scenario's broadcasts fan out in batches
    assert q[CO.Q_CHAN] == 1  # and its hops go through channels
    assert S[L.BAT_T].shape == (2 * S[L.HEAP_T].size,)
    assert S[L.FREE].tolist() == list(range(S[L.HEAP_T].size))[::-1]


def test_exit_codes_are_distinct_and_all_registered() -> None:
    # two parts of the core once both took code 7 (a draw fill was served as a
    # re-simulation, and the loop asked again forever)
    codes = CO.EXIT_CODES
    assert len(set(codes.values())) == len(codes)
    named = {k for k, v in vars(CO).items() if k.startswith("NEED_") and isinstance(v, int)}
    assert named | {"OK", "DRAW_MISS", "BARRIER"} == set(codes)
    assert all(getattr(CO, k) == v for k, v in codes.items())


def test_event_types_are_distinct() -> None:
    types = (CO.EV_BROKER, CO.EV_CLIENT, CO.EV_DONE, CO.EV_RESEND, CO.EV_SEND, CO.EV_APP)
    assert sorted(types) == list(range(6))


def test_a_deployment_follows_the_network() -> None:
    """Processes, machines, demands and per-host clients as the spec's Network and Cpu
    hold them (3 nodes on 2 hosts: host 0 holds nodes 0 and 1, host 1 node 2)."""
    sc = replace(tiny(**{"deployment.preset": "dedicated", "deployment.cores": 3,
                         "deployment.background": 1.0, "deployment.server_demand": 0.001,
                         "deployment.clients": "host",
                         "broker.publish_service": 0.0001}), engine="cohort")
    run = MethodRun(sc.run_spec(), "none", make_dynamics(sc), make_behaviour(sc), compiled=True)
    core = run.core
    assert isinstance(core, CompiledCore)
    S = core.S
    assert sc.run_spec().net.topology.host_of == (0, 0, 1)
    ip = S[L.CPU_IP]
    assert ip[CO.CP_BROKER] == CO.P_BROKER and ip[CO.CP_HOSTS] == 1 and ip[CO.CP_APP] == 1
    # dedicated: broker, server, host 0, host 1 on machines 0..3 of 3 cores; 3 / (3 - 1)
    assert S[L.CPU_MACH].tolist() == [0, 1, 2, 3]
    assert S[L.CPU_IV].shape == (4, 3, RESERVATIONS + 1, 2) and S[L.CPU_NIV].shape == (4, 3)
    assert S[L.CPU_SCALE].tolist() == [1.5] * 4
    # host demand 0: the nodes' clients make no bursts; the server's do
    assert S[L.CPU_PROC].tolist() == [-1, -1, -1, CO.P_SERVER]
    assert S[L.CPU_DEM].tolist() == [0.0, 0.0, 0.0, 0.001]
    # host h's client is its first node; a trigger goes to clients 0 and 2, and client 0
    # hands it to nodes 0 and 1, client 2 to node 2
    assert S[L.CL_OF].tolist() == [0, 0, 2, 3]
    assert ip[CO.CP_NSUB] == 2 and S[L.BCAST][:2].tolist() == [0, 2]
    assert ip[CO.CP_MAXMEM] == 2  # a trigger's hand-over adds up to 2 latencies at once
    ptr, mem = S[L.MEM_PTR], S[L.MEM]
    assert [mem[ptr[c]:ptr[c + 1]].tolist() for c in range(4)] == [[0, 1], [], [2], []]
