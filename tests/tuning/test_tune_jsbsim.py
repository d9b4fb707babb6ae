"""JSBSim F450 logs: valid logs whose measured propeller speeds, replayed through our
preset with a negligible motor lag, already reproduce JSBSim's roll and pitch (checks the
engine order, spin senses and units; a swapped pair of motors fails it)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jsbsim")

from sigma_des.agents.presets import preset  # noqa: E402
from sigma_des.tuning.jsbsim_log import fly_f450  # noqa: E402
from sigma_des.tuning.report import replayed, score  # noqa: E402
from sigma_des.tuning.spec import TuneSpec, with_values  # noqa: E402
from sigma_des.tuning.synth import Noise  # noqa: E402


def test_f450_log_replays_through_our_preset() -> None:
    log = fly_f450(duration=4.0, noise=Noise(0.0, 0.0, 0.0, 0.0))
    assert log.t.shape == (201,) and log.act.shape == (201, 4)
    assert np.all((log.act > 300) & (log.act < 800))          # spinning, below omega_max
    assert np.abs(log.obs[:, 3]).max() > 0.1                  # it manoeuvred
    p = with_values(preset("quadrotor"), {"tau_motor": 0.001})
    swapped = log.act[:, [2, 1, 0, 3]]
    bad = type(log)(log.kind, log.t, swapped, log.obs, "swapped")
    spec = TuneSpec()
    win, sims = replayed(log, [p], spec)
    good = score(win, sims[0], "quadrotor")
    assert good["r2"] > 0.9
    win_b, sims_b = replayed(bad, [p], spec)
    assert score(win_b, sims_b[0], "quadrotor")["r2"] < 0.5
