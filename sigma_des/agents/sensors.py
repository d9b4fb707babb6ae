"""Onboard sensors: IMU, magnetometer, barometer and GPS as pure functions of the state.

Every channel ``c`` reads ``(1 + s_c) * ideal + b_c + sigma_c * eta + vib_c`` where

* ``eta`` is a counter-based standard normal keyed by (node id, frame, channel) —
  reading the same node at the same frame twice gives the same value;
* the scale error ``s_c ~ N(0, scale_std)`` and the turn-on bias
  ``b_c ~ N(bias_mean, bias_std)`` are drawn once per (node, channel) from their
  own streams, so each simulated unit has its own fixed calibration error;
* ``vib_c = A_c (Omega / Omega_ref)^2 (sin(Omega t + p1) + 0.5 sin(2 Omega t + p2))``
  on accelerometer and gyro channels: rotor imbalance at the rotor frequency and
  blade passage (2 blades) at twice it, amplitude growing with the centrifugal
  imbalance force ``~ Omega^2``; ``Omega`` is the mean rotor speed, the phases
  are per (node, channel).

Ideal values: specific force ``(F_aero + F_rotor) / m`` in body axes (what an
accelerometer senses, in the same wind as the dynamics), body rates, the Earth
field (50 uT, inclination 60 deg, declination 0) in body axes, altitude (baro)
and NED position/velocity (GPS). Noise figures are per sample at the frame rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import NDArray

from sigma_des.agents import layout as L
from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.atmosphere import isa_scalar
from sigma_des.agents.forces import forces_moments
from sigma_des.agents.rigid_body import rotmat, to_body, to_ned
from sigma_des.agents.wind import mean_wind
from sigma_des.core.counter_rng import absorb, normal_at
from sigma_des.core.rng import RandomStreams
from sigma_des.errors import ConfigError

__all__ = ["SENSOR_FIELDS", "ChannelNoise", "SensorConfig", "Sensors"]

#: Output columns of :meth:`Sensors.read`.
SENSOR_FIELDS: tuple[str, ...] = (
    "acc_x", "acc_y", "acc_z", "gyro_p", "gyro_q", "gyro_r", "mag_x", "mag_y", "mag_z",
    "baro_h", "gps_n", "gps_e", "gps_h", "gps_vn", "gps_ve", "gps_vd",
)
_B_EARTH = 50.0                   # uT, mid-latitude total field (WMM order of magnitude)
_INCL = math.radians(60.0)        # inclination (dip), mid-latitude


@dataclass(frozen=True)
class ChannelNoise:
    """Error model of one sensor (applied to each of its axes).

    Attributes:
        sigma: white-noise standard deviation per sample.
        bias_mean: mean turn-on bias.
        bias_std: standard deviation of the turn-on bias across units.
        scale_std: standard deviation of the scale-factor error (fraction).
        vib: vibration amplitude at ``SensorConfig.omega_ref`` (IMU only).
    """

    sigma: float = 0.0
    bias_mean: float = 0.0
    bias_std: float = 0.0
    scale_std: float = 0.0
    vib: float = 0.0

    def __post_init__(self) -> None:
        for k in ("sigma", "bias_std", "scale_std", "vib"):
            v = getattr(self, k)
            if not (v >= 0 and math.isfinite(v)):
                raise ConfigError(f"sensors.{k}", f"must be a finite number >= 0, got {v}")


@dataclass(frozen=True)
class SensorConfig:
    """Error models of every sensor; defaults are typical small-UAV parts.

    Attributes:
        accel: m/s^2. MPU-6000 class: 400 ug/sqrt(Hz) -> ~0.03 m/s^2 at 100 Hz;
            residual bias after calibration ~5 mg; vibration 2 m/s^2 at hover
            (ArduPilot "good" vibration level is < 15 m/s^2 peak).
        gyro: rad/s. MPU-6000: 0.005 deg/s/sqrt(Hz) -> ~1e-3 rad/s; bias ~0.3 deg/s.
        mag: uT. HMC5883L: 2 mG = 0.2 uT resolution; hard-iron residual ~1 uT.
        baro: m. MS5611: 0.012 mbar RMS at OSR 4096 ~ 0.1 m; faster rates and
            prop wash ~0.3 m; bias ~1 m (weather / ground-pressure offset).
        gps_pos: m (all three axes). u-blox M8: 2.5 m CEP -> sigma ~2 m.
        gps_vel: m/s. u-blox M8: 0.05 m/s.
        omega_ref: rotor speed at which ``vib`` is specified (rad/s).
    """

    accel: ChannelNoise = field(default_factory=lambda: ChannelNoise(0.03, 0.0, 0.05, 0.005, 2.0))
    gyro: ChannelNoise = field(default_factory=lambda: ChannelNoise(1e-3, 0.0, 5e-3, 0.003, 0.02))
    mag: ChannelNoise = field(default_factory=lambda: ChannelNoise(0.3, 0.0, 1.0, 0.01, 0.0))
    baro: ChannelNoise = field(default_factory=lambda: ChannelNoise(0.3, 0.0, 1.0, 0.0, 0.0))
    gps_pos: ChannelNoise = field(default_factory=lambda: ChannelNoise(2.0, 0.0, 0.0, 0.0, 0.0))
    gps_vel: ChannelNoise = field(default_factory=lambda: ChannelNoise(0.05, 0.0, 0.0, 0.0, 0.0))
    omega_ref: float = 515.0

    def table(self) -> NDArray[np.float64]:
        """``(16, 5)`` per-channel ``[sigma, bias_mean, bias_std, scale_std, vib]``."""
        rows = ([self.accel] * 3 + [self.gyro] * 3 + [self.mag] * 3 + [self.baro]
                + [self.gps_pos] * 3 + [self.gps_vel] * 3)
        return np.array([[c.sigma, c.bias_mean, c.bias_std, c.scale_std, c.vib] for c in rows])


@njit(cache=True)
def _sensor_kernel(state: np.ndarray, nodes: np.ndarray, frame: np.int64, prm: np.ndarray,
                   key: np.uint64, tab: np.ndarray, cal: np.ndarray, omega_ref: float,
                   noisy: bool, out: np.ndarray) -> None:
    """Measurements of every row; ``cal[i]`` = per-unit [bias(16) scale(16) cos p, sin p (24)]."""
    n = state.shape[0]
    ideal = np.empty(16)
    for i in range(n):
        x = state[i]
        rm = rotmat(x)
        _, _, rho = isa_scalar(x[L.H])
        wn, we, wd = mean_wind(prm, x[L.TIME], x[L.H])
        hn = math.sqrt(rm[0] * rm[0] + rm[3] * rm[3])
        ch, sh = (rm[0] / hn, rm[3] / hn) if hn > 1e-9 else (1.0, 0.0)
        wn += ch * x[L.TU] - sh * x[L.TV]
        we += sh * x[L.TU] + ch * x[L.TV]
        wd += x[L.TW]
        bx, by, bz = to_body(rm, wn, we, wd)
        fx, fy, fz, _, _, _ = forces_moments(x, prm, bx, by, bz, rho)
        m = prm[L.MASS]
        ideal[0], ideal[1], ideal[2] = fx / m, fy / m, fz / m
        ideal[3], ideal[4], ideal[5] = x[L.P], x[L.Q], x[L.R]
        ideal[6], ideal[7], ideal[8] = to_body(rm, _B_EARTH * math.cos(_INCL), 0.0,
                                               _B_EARTH * math.sin(_INCL))
        ideal[9] = x[L.H]
        ideal[10], ideal[11], ideal[12] = x[L.XN], x[L.YE], x[L.H]
        ideal[13], ideal[14], ideal[15] = to_ned(rm, x[L.U], x[L.V], x[L.W])
        if not noisy:
            for c in range(16):
                out[i, c] = ideal[c]
            continue
        h2 = absorb(absorb(key, nodes[i]), frame)
        for c in range(16):
            out[i, c] = ((1.0 + cal[i, 16 + c]) * ideal[c] + cal[i, c]
                         + tab[c, 0] * normal_at(h2, c))  # type: ignore[arg-type]
        nrot = int(prm[L.NROT])
        om = 0.0
        for j in range(nrot):
            om += x[L.OM0 + j]
        om /= max(nrot, 1)
        if om > 0.0:
            # 1P and 2P harmonics; phases enter through precomputed cos/sin so
            # only one sin/cos pair is evaluated per row.
            k = (om / omega_ref) ** 2
            s1, c1 = math.sin(om * x[L.TIME]), math.cos(om * x[L.TIME])
            s2, c2 = 2.0 * s1 * c1, c1 * c1 - s1 * s1
            for c in range(6):
                a = tab[c, 4]
                if a > 0.0:
                    b = 32 + 4 * c
                    out[i, c] += a * k * (s1 * cal[i, b] + c1 * cal[i, b + 1]
                                          + 0.5 * (s2 * cal[i, b + 2] + c2 * cal[i, b + 3]))


class Sensors:
    """Sensor suite of a :class:`GeneralAircraft` swarm (see module docstring).

    Args:
        model: the aircraft model (its parameters give forces and rotor speeds).
        config: error models.
        seed: root seed of the noise, bias, scale and phase streams.
    """

    fields = SENSOR_FIELDS

    def __init__(self, model: GeneralAircraft, config: SensorConfig | None = None,
                 seed: int = 0) -> None:
        self.model = model
        self.config = config or SensorConfig()
        if not self.config.omega_ref > 0:
            raise ConfigError("sensors.omega_ref", f"must be > 0, got {self.config.omega_ref}")
        self._streams = RandomStreams(seed)
        self.key = self._streams.stream("agents.sensors.noise").key
        self.table = self.config.table()
        self._cal_nodes: NDArray[np.int64] | None = None
        self._cal = np.zeros((0, 56))

    def calibration(self, nodes: NDArray[np.int64]) -> NDArray[np.float64]:
        """Per-unit constants ``(n, 56)``: bias (16), scale error (16), vibration phases.

        Drawn with :class:`sigma_des.core.rng.Stream` keyed by (node, channel), so a node
        keeps its calibration error whatever batch it is read in; cached for the
        last ``nodes`` array seen.
        """
        if self._cal_nodes is not None and np.array_equal(nodes, self._cal_nodes):
            return self._cal
        ch = np.arange(16)[None, :]
        nd = nodes[:, None]
        tab = self.table
        cal = np.empty((nodes.shape[0], 56))
        st = self._streams.stream
        cal[:, :16] = tab[:, 1] + tab[:, 2] * st("agents.sensors.bias").normal(nd, ch)
        cal[:, 16:32] = tab[:, 3] * st("agents.sensors.scale").normal(nd, ch)
        ph = 2 * np.pi * st("agents.sensors.phase").uniform(nd, np.arange(12)[None, :])
        # Per IMU channel c: cos p1, sin p1, cos p2, sin p2 (sin(wt+p) = s cos p + c sin p).
        cal[:, 32:56:4], cal[:, 33:56:4] = np.cos(ph[:, 0::2]), np.sin(ph[:, 0::2])
        cal[:, 34:56:4], cal[:, 35:56:4] = np.cos(ph[:, 1::2]), np.sin(ph[:, 1::2])
        self._cal_nodes, self._cal = nodes.copy(), cal
        return cal

    def read(self, state: NDArray[np.float64], nodes: NDArray[np.int64],
             frame: int) -> NDArray[np.float64]:
        """``(n, 16)`` measurements, columns :data:`SENSOR_FIELDS`."""
        return self._run(state, nodes, frame, True)

    def ideal(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """``(n, 16)`` error-free values of the same channels."""
        return self._run(state, np.zeros(state.shape[0], dtype=np.int64), 0, False)

    def _run(self, state: NDArray[np.float64], nodes: NDArray[np.int64], frame: int,
             noisy: bool) -> NDArray[np.float64]:
        state = np.ascontiguousarray(state, dtype=np.float64)
        nodes = np.ascontiguousarray(nodes, dtype=np.int64)
        out = np.empty((state.shape[0], 16))
        cal = self.calibration(nodes) if noisy else np.zeros((state.shape[0], 56))
        _sensor_kernel(state, nodes, np.int64(frame), self.model.prm, self.key, self.table,
                       cal, self.config.omega_ref, noisy, out)
        return out
