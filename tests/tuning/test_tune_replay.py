"""Replay and fitness: the batched flight equals one-by-one replays bit for bit, the true
parameters reproduce a clean log exactly, and r = D T / s by hand."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.agents.aircraft import observe_state
from sigma_des.agents.presets import preset
from sigma_des.metrics.dtw import dtw, dtw_rows
from sigma_des.tuning.fitness import FitnessSpec, fit_metrics, fitness
from sigma_des.tuning.flightlog import resample
from sigma_des.tuning.ga import Evaluator
from sigma_des.tuning.replay import (
    Windows,
    param_matrix,
    replay_batch,
    replay_serial,
    state_from_obs,
    windows,
)
from sigma_des.tuning.spec import with_values
from sigma_des.tuning.synth import Noise, fly

CLEAN = Noise(0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("kind", ["quadrotor", "fixedwing"])
def test_batch_equals_serial_and_truth_replays_exactly(kind: str) -> None:
    truth = preset(kind)
    log = fly(truth, kind, duration=3.0, noise=CLEAN)
    win = windows(resample(log, 50.0), 0.5)
    assert win.count == 6 and win.steps == 25
    cands = [truth, with_values(truth, {"ixx": truth.ixx * 1.3}),
             with_values(truth, {"tau_motor": truth.tau_motor * 0.6, "cd_0": 0.3})]
    batch = replay_batch(win, param_matrix(cands))
    for i, c in enumerate(cands):
        assert np.array_equal(batch[i], replay_serial(win, c))
    # The truth reproduces the log it flew (same commands, same steps): exactly.
    assert np.abs(batch[0] - win.obs).max() < 1e-9
    assert np.abs(batch[1] - win.obs).max() > 1e-3
    r = fitness(win, batch, FitnessSpec.of(win, ("phi", "theta", "p", "q")))
    assert r[0] < 1e-9 < r[1] and r[2] > 1e-9


def test_state_from_obs_round_trip() -> None:
    rng = np.random.default_rng(0)
    obs = rng.uniform(-1, 1, (20, 12))
    obs[:, 4] *= 1.5   # theta within +-pi/2
    s = state_from_obs(obs, np.zeros(20), np.zeros((20, 7)))
    assert np.allclose(observe_state(s), obs, atol=1e-12)


def _const_windows(offset: float) -> tuple[Windows, np.ndarray]:
    obs = np.zeros((2, 5, 12))
    obs[:, :, 9] = np.arange(5) * 0.5          # x: 2 m per window of 4 steps
    win = Windows(dt=0.1, steps=4, start=np.zeros((2, 28)), act=np.zeros((2, 4, 7)), obs=obs)
    sim = np.broadcast_to(obs, (1, 2, 5, 12)).copy()
    sim[..., 4] += offset                      # theta off by a constant
    return win, sim


def test_fitness_by_hand() -> None:
    win, sim = _const_windows(0.1)
    spec = FitnessSpec.of(win, ("theta",))
    assert spec.duration == pytest.approx(0.8) and spec.distance == pytest.approx(4.0)
    # Constant offset 0.1 over 5 points: DTW = 0.5 per window (the diagonal is optimal),
    # D = 1.0 over both windows, r = D T / s = 1.0 * 0.8 / 4.0.
    assert fitness(win, sim, spec)[0] == pytest.approx(0.2)
    m = fit_metrics(win, sim[0], ("theta", "x"))
    assert m["theta"]["rms"] == pytest.approx(0.1)
    assert m["x"]["r2"] == 1.0 and m["x"]["rms"] == 0.0
    sim[0, 1, 2, 4] = np.nan
    assert fitness(win, sim, spec)[0] == np.inf


def test_r2_and_rms_by_hand() -> None:
    """Two windows of 4 steps, theta = 0, 1, 2, 3, 4 logged; the replay off by +-0.5 after
    the start. Scored samples (starts excluded): 1, 2, 3, 4 twice, mean 2.5, SS_tot =
    2 (2.25 + 0.25 + 0.25 + 2.25) = 10, SS_res = 8 x 0.25 = 2: R² = 0.8, RMS = 0.5."""
    obs = np.zeros((2, 5, 12))
    obs[:, :, 4] = np.arange(5.0)
    win = Windows(dt=0.1, steps=4, start=np.zeros((2, 28)), act=np.zeros((2, 4, 7)), obs=obs)
    sim = obs.copy()
    sim[:, :, 4] += np.array([9.0, 0.5, -0.5, 0.5, -0.5])   # the start is not scored
    m = fit_metrics(win, sim, ("theta",))["theta"]
    assert m["r2"] == pytest.approx(0.8) and m["rms"] == pytest.approx(0.5)
    sim[:, :, 4] = 2.5                                        # the mean: R² = 0
    assert fit_metrics(win, sim, ("theta",))["theta"]["r2"] == pytest.approx(0.0)


def test_dtw_rows_matches_dtw_and_band() -> None:
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(3, 30, 2)), rng.normal(size=(3, 30, 2))
    full = dtw_rows(a, b)
    assert np.array_equal(full, [dtw(a[i], b[i]) for i in range(3)])
    diag = np.sqrt(((a - b) ** 2).sum(axis=2)).sum(axis=1)
    assert np.allclose(dtw_rows(a, b, 0), diag)             # band 0: no warping
    wide = dtw_rows(a, b, 29)
    assert np.array_equal(wide, full)                      # band covering all = exact DTW
    mid = dtw_rows(a, b, 3)
    assert np.all(full <= mid) and np.all(mid <= diag)


def test_evaluator_ranks_truth_first() -> None:
    """A fitness that ignored the trajectory could not put the truth strictly first."""
    truth = preset("quadrotor")
    log = fly(truth, "quadrotor", duration=3.0, seed=3)
    win = windows(resample(log, 50.0), 1.0)
    names = ("ixx", "rotor_pitch")
    ev = Evaluator(win, truth, names, ("phi", "theta", "h"), band=3)
    xs = np.array([[truth.ixx, truth.rotor_pitch], [truth.ixx * 1.2, truth.rotor_pitch],
                   [truth.ixx, truth.rotor_pitch * 0.95], [truth.ixx * 0.8, truth.rotor_pitch]])
    r = ev(xs)
    assert np.argmin(r) == 0 and np.all(r[1:] > 1.05 * r[0])
