"""PointMass's compiled paths (step, step_frames, observe_into, the rollback re-simulation
into the truth's ring) give the bits of its array formulas."""

from __future__ import annotations

import ctypes
import ctypes.util
import math

import numpy as np
import pytest

from sigma_des.agents.pointmass import PointMass
from sigma_des.events.truth import SwarmTruth


def test_step_frames_equals_frame_by_frame_steps_bitwise() -> None:
    pm = PointMass(tau=0.37)
    state = pm.initial_state(4)
    state[:, 3:6] = np.random.default_rng(1).normal(0.0, 3.0, (4, 3))
    cmd = np.array([12.5, -3.25, 0.7])
    dts = np.array([0.02, 0.02, 0.025, 1.0 / 48.0, 0.02, 0.0125])
    got = pm.step_frames(state[2], cmd, dts, 40, 2)
    s = state[2:3]
    for j, dt in enumerate(dts):
        s = pm.step(s, cmd[None, :], float(dt), 40 + j, np.array([2]))
        np.testing.assert_array_equal(got[j], s[0])
    assert got.shape == (6, 6) and not np.array_equal(got[-1], state[2])



def test_step_frames_at_one_rate_equals_frame_by_frame_steps_bitwise() -> None:
    """All frames at one step (the gain computed once) give the per-frame steps' bits;
    an empty span gives no rows."""
    pm = PointMass(tau=0.41)
    s0 = np.array([3.0, -7.5, 98.0, 9.5, 1.25, -0.3])
    cmd = np.array([-4.0, 6.5, 1.1])
    for dt in (0.02, 1.0 / 48.0):
        dts = np.full(23, dt)
        got = pm.step_frames(s0, cmd, dts, 5, 1)
        s = s0[None, :]
        for j in range(dts.size):
            s = pm.step(s, cmd[None, :], dt, 5 + j, np.array([1]))
            np.testing.assert_array_equal(got[j], s[0])
    assert pm.step_frames(s0, cmd, np.zeros(0), 5, 1).shape == (0, 6)

def test_hand_computed_first_frame() -> None:
    # tau = dt / ln 2: the gain 1 - exp(-ln 2) is 1/2 up to rounding
    pm = PointMass(tau=0.5)
    dt = 0.5 * np.log(2.0)
    a = 1.0 - np.exp(-dt / 0.5)
    got = pm.step_frames(np.array([1.0, 2.0, 100.0, 10.0, 0.0, 0.0]), np.array([0.0, 4.0, 2.0]),
                         np.array([dt]), 0, 0)
    v1 = np.array([10.0 + a * (0.0 - 10.0), 0.0 + a * 4.0, 0.0 + a * 2.0])
    assert abs(a - 0.5) < 1e-15
    np.testing.assert_array_equal(got[0, 3:6], v1)
    np.testing.assert_array_equal(got[0, 0:3], np.array([1.0, 2.0, 100.0])
                                  + 0.5 * (np.array([10.0, 0.0, 0.0]) + v1) * dt)


def test_point_mass_rollbacks_stay_immediate_and_match_the_frame_loop() -> None:
    """A rollback re-simulates at once through step_frames (not deferred), with the bits
    of the former per-frame loop over ``step``."""
    n, H = 5, 8
    truth = SwarmTruth(PointMass(), n, H, 10.0, True)
    assert not truth.batched
    rng = np.random.default_rng(4)
    cmd = truth.dyn.default_command(truth.state)
    for k in range(11):
        cmd = cmd + rng.normal(0.0, 0.5, cmd.shape)
        truth.step_frame(k, 0.02 + 0.001 * (k % 3), cmd, None)
    row = np.array([3.0, -1.0, 0.5])
    c = 6
    # the reference: the per-frame loop from the checkpoint of frame c - 1
    s = truth.ckpt[(c - 1) % H, 1][None, :].copy()
    ref = []
    for f in range(c, truth.latest + 1):
        s = truth.dyn.step(s, row[None, :], float(truth.frame_dt[f % H]), f, np.array([1]))
        ref.append(s[0])
    assert truth.rollback(1, c, 12, row) == 12 - c + 1
    for f, want in zip(range(c, truth.latest + 1), ref, strict=True):
        np.testing.assert_array_equal(truth.ckpt[f % H, 1], want)
        np.testing.assert_array_equal(truth.obs_hist[f % H, 1], truth.dyn.observe(want[None])[0])
    np.testing.assert_array_equal(truth.state[1], ref[-1])


def _libm() -> ctypes.CDLL:
    """The C library's math (Python's ``math.hypot`` is CPython's own algorithm)."""
    name = ctypes.util.find_library("m")
    if name is None:
        pytest.skip("no C math library to compare with")
    lib = ctypes.CDLL(name)
    for fn in (lib.hypot, lib.atan2):
        fn.restype, fn.argtypes = ctypes.c_double, [ctypes.c_double, ctypes.c_double]
    return lib


def test_observe_into_is_observe_bitwise() -> None:
    """Both observations are the C library's hypot and atan2 bit for bit, on any machine
    (numpy's float64 ufuncs are SIMD code on AVX-512 machines and differ there)."""
    libc = _libm()
    pm = PointMass()
    rng = np.random.default_rng(8)
    for scale in (1e-3, 1.0, 30.0, 1e6):
        state = rng.normal(0.0, scale, (4000, 6))
        state[:6, 3:6] = [[0.0, 0.0, 0.0], [-0.0, 0.0, -0.0], [0.0, -0.0, 1.0],
                          [-1.0, 0.0, 0.0], [1e-310, 1e-310, 2.0], [5.0, 5.0, -5.0]]
        out = np.full((4000, 12), np.nan)
        pm.observe_into(state, out)
        want = pm.observe(state)
        assert out.tobytes() == want.tobytes()  # -0.0 and 0.0 told apart too
        libm = np.zeros((4000, 12))
        for r, (x, y, z, vn, ve, vh) in enumerate(state):
            libm[r, [0, 2, 5, 9, 10, 11]] = [libc.hypot(vn, ve), -vh, libc.atan2(ve, vn),
                                             x, y, z]
        assert want.tobytes() == libm.tobytes()
    assert want[3, 5] == np.pi and want[5, 0] == math.hypot(5.0, 5.0) and want[5, 2] == 5.0
    # a strided view observes as its copy
    assert pm.observe(state[::2]).tobytes() == pm.observe(state[::2].copy()).tobytes()


def _no_ring_call(pm: PointMass) -> object:
    """``pm`` seen without its one-call re-simulation (the truth's step_frames path)."""

    class Plain:
        name, state_dim, command_dim = pm.name, pm.state_dim, pm.command_dim
        defer_rollbacks = False

        def __getattr__(self, item: str) -> object:
            if item in ("resimulate_into", "observe_into"):
                raise AttributeError(item)
            return getattr(pm, item)

    return Plain()


def test_rollbacks_through_resimulate_into_equal_the_step_frames_path() -> None:
    """Rollbacks of drawn nodes, frames and rows over a wrapping ring at varying steps:
    the one-call re-simulation writes the ring, checkpoints and state of step_frames and
    observe, bit for bit."""
    n, H = 6, 16
    pm = PointMass(tau=0.43)
    fast = SwarmTruth(pm, n, H, 10.0, True)
    ref = SwarmTruth(_no_ring_call(pm), n, H, 10.0, True)  # type: ignore[arg-type]
    assert fast._resimulate_into is not None and ref._resimulate_into is None
    rng = np.random.default_rng(12)
    cmd = pm.default_command(fast.state)
    for k in range(60):
        cmd = cmd + rng.normal(0.0, 0.8, cmd.shape)
        dt = [0.02, 0.025, 1.0 / 48.0][int(rng.integers(3))]
        for t in (fast, ref):
            t.step_frame(k, dt, cmd, None)
        if k > 3 and rng.random() < 0.6:
            i = int(rng.integers(n))
            c = int(rng.integers(max(1, k - H + 2), k + 1))
            row = rng.normal(0.0, 5.0, 3)
            assert fast.rollback(i, c, k, row) == ref.rollback(i, c, k, row)
        held = np.arange(max(0, k - H + 1), k + 1) % H  # slots written so far (np.empty)
        for a, b in ((fast.ckpt[held], ref.ckpt[held]), (fast.obs_hist[held], ref.obs_hist[held]),
                     (fast.state, ref.state)):
            assert a.tobytes() == b.tobytes()
    assert fast.rollbacks == ref.rollbacks > 10


def test_compiled_step_is_the_array_formula_bitwise() -> None:
    """PointMass.step (compiled for one command row per state row) gives the bits of its
    array formula; a broadcast command row takes the array path, the same values."""
    rng = np.random.default_rng(21)
    for tau in (0.5, 0.37):
        pm = PointMass(tau=tau)
        for _ in range(50):
            n = int(rng.integers(1, 40))
            state = rng.normal(0.0, 50.0, (n, 6))
            cmd = rng.normal(0.0, 12.0, (n, 3))
            dt = float(rng.choice([0.02, 1.0 / 48.0, 0.1, float(rng.uniform(0.001, 0.2))]))
            a = 1.0 - math.exp(-dt / tau)  # the model's gain (Python's libm exp)
            v0 = state[:, 3:6]
            v1 = v0 + a * (cmd - v0)
            want = np.concatenate([state[:, 0:3] + 0.5 * (v0 + v1) * dt, v1], axis=1)
            got = pm.step(state, cmd, dt, 3, np.arange(n))
            assert got.tobytes() == want.tobytes()
            row = pm.step(state, cmd[:1], dt, 3, np.arange(n))  # (1, 3): broadcast
            assert row.tobytes() == pm.step(state, np.repeat(cmd[:1], n, 0), dt, 3,
                                            np.arange(n)).tobytes()
