"""Sensor error models: statistics match the configuration; readings are keyed, not sequential."""

from __future__ import annotations

import numpy as np
import pytest

from sigma_des.agents import layout as L
from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.sensors import SENSOR_FIELDS, ChannelNoise, SensorConfig, Sensors
from sigma_des.errors import ConfigError


def test_ideal_values_at_hover() -> None:
    m = GeneralAircraft("quadrotor")
    ideal = Sensors(m).ideal(m.initial_state(1))[0]
    assert ideal[2] == pytest.approx(-9.806, abs=2e-3)      # rotors carry the weight
    np.testing.assert_allclose(ideal[[0, 1, 3, 4, 5]], 0.0, atol=1e-9)
    assert ideal[SENSOR_FIELDS.index("baro_h")] == 100.0
    assert np.linalg.norm(ideal[6:9]) == pytest.approx(50.0)


def test_noise_bias_and_scale_statistics_match_configuration() -> None:
    acc = ChannelNoise(sigma=0.2, bias_mean=0.3, bias_std=0.1, scale_std=0.0)
    cfg = SensorConfig(accel=acc, gyro=ChannelNoise(sigma=0.01),
                       baro=ChannelNoise(sigma=0.5, bias_std=2.0))
    m = GeneralAircraft("fixedwing")           # no vibration: propeller on the x axis only
    sen = Sensors(m, cfg, seed=4)
    n = 300
    s = m.initial_state(n)
    nodes = np.arange(n, dtype=np.int64)
    ideal = sen.ideal(s)
    reads = np.array([sen.read(s, nodes, f) for f in range(200)]) - ideal   # (F, n, 16)
    cal = sen.calibration(nodes)
    # Per-node mean over frames = that node's bias; residual std = sigma.
    np.testing.assert_allclose(reads[..., 0].mean(0), cal[:, 0], atol=4 * 0.2 / np.sqrt(200))
    resid = reads[..., 0] - cal[:, 0]
    assert resid.std() == pytest.approx(0.2, rel=0.03)
    assert abs(resid.mean()) < 0.005
    assert reads[..., 3].std() == pytest.approx(0.01, rel=0.03)
    # Biases across units: mean and spread as configured.
    assert cal[:, 0:3].mean() == pytest.approx(0.3, abs=0.02)
    assert cal[:, 0:3].std() == pytest.approx(0.1, rel=0.1)
    assert cal[:, 9].std() == pytest.approx(2.0, rel=0.15)
    # Same (node, frame) -> same reading; another frame -> a different one.
    np.testing.assert_array_equal(sen.read(s, nodes, 7), sen.read(s, nodes, 7))
    assert not np.array_equal(sen.read(s, nodes, 7), sen.read(s, nodes, 8))
    # A node reads the same alone as in the batch.
    np.testing.assert_array_equal(sen.read(s[5:6], nodes[5:6], 7)[0], sen.read(s, nodes, 7)[5])


def test_scale_error_multiplies_the_ideal_value() -> None:
    cfg = SensorConfig(mag=ChannelNoise(scale_std=0.05), accel=ChannelNoise(),
                       gyro=ChannelNoise())
    m = GeneralAircraft("fixedwing")
    sen = Sensors(m, cfg, seed=1)
    s = m.initial_state(500)
    nodes = np.arange(500, dtype=np.int64)
    r = sen.read(s, nodes, 0)
    ideal = sen.ideal(s)
    ratio = r[:, 6] / ideal[:, 6]
    assert ratio.mean() == pytest.approx(1.0, abs=0.01)
    assert ratio.std() == pytest.approx(0.05, rel=0.15)


def test_vibration_grows_with_rotor_speed() -> None:
    cfg = SensorConfig(accel=ChannelNoise(vib=1.0), gyro=ChannelNoise(), omega_ref=500.0)
    m = GeneralAircraft("quadrotor")
    sen = Sensors(m, cfg)
    nodes = np.arange(1, dtype=np.int64)

    def rms(omega: float) -> float:
        s = m.initial_state(1)
        s[:, L.OM0:L.OM0 + 4] = omega
        vals = []
        for k in range(400):
            s[:, L.TIME] = k * 0.00123
            vals.append(sen.read(s, nodes, k)[0, 0] - sen.ideal(s)[0, 0])
        return float(np.sqrt(np.mean(np.square(vals))))

    lo, hi = rms(250.0), rms(500.0)
    assert hi == pytest.approx(4 * lo, rel=0.1)               # amplitude ~ omega^2
    assert hi == pytest.approx(np.sqrt(0.5 + 0.125), rel=0.1)  # 1P + 0.5 x 2P sines


def test_bad_sensor_config_names_the_field() -> None:
    with pytest.raises(ConfigError, match="sensors.sigma"):
        ChannelNoise(sigma=-1.0)
