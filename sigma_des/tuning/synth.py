"""Synthetic flight logs flown by our own model: the ground truth of the identifiability test.

:func:`fly` flies a high-manoeuvrability attitude manoeuvre (doublets in roll
and pitch, a yaw sweep) with a simple attitude controller at the log rate,
through the aircraft's open-loop actuator interface, so the logged control
signals are exactly what the airframe was told, sample-and-hold, as in an
offboard-mode log. The true aircraft may fly in wind and turbulence; the
logged state carries seeded Gaussian sensor noise (:class:`Noise`). Nothing
here is needed to tune from real logs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents import layout as L
from sigma_des.agents.aircraft import GeneralAircraft
from sigma_des.agents.params import AircraftParams
from sigma_des.agents.wind import WindConfig
from sigma_des.core.rng import RandomStreams
from sigma_des.tuning.flightlog import FlightLog

__all__ = ["Noise", "fly", "manoeuvre"]


@dataclass(frozen=True)
class Noise:
    """Sensor noise standard deviations of the logged state (0 = exact).

    Attributes:
        angle: attitude angles (rad).
        rate: body rates (rad/s).
        position: position (m).
        velocity: body velocity (m/s).
    """

    angle: float = 0.005
    rate: float = 0.02
    position: float = 0.02
    velocity: float = 0.05


def manoeuvre(t: float, kind: str, amp: float, variant: int) -> tuple[float, float, float]:
    """Roll, pitch and yaw references (rad) at time ``t``: doublets and a yaw sweep.

    ``variant`` shifts the doublet timing and the sweep frequency, so a second
    variant is a different (validation) manoeuvre.
    """
    per = 2.0 + 0.7 * variant
    k = math.floor(t / per)
    ph = (t - k * per) / per
    dbl = 1.0 if ph < 0.25 else (-1.0 if ph < 0.5 else 0.0)
    roll = amp * dbl if k % 2 == 0 else 0.5 * amp * dbl
    pitch = amp * dbl if k % 2 == 1 else -0.5 * amp * dbl
    if kind == "fixedwing":
        return roll, 0.4 * pitch, 0.0
    return roll, pitch, 0.4 * math.sin(2 * math.pi * t / (5.0 + 2.0 * variant))


def _quad_control(model: GeneralAircraft, obs: NDArray[np.float64],
                  ref: tuple[float, float, float], h_ref: float) -> NDArray[np.float64]:
    p = model.params
    prm = model.prm
    u, v, w, phi, th, psi, pr, qr, rr = obs[:9]
    vz = -(-math.sin(th) * u + math.sin(phi) * math.cos(th) * v
           + math.cos(phi) * math.cos(th) * w)
    wn, z = 9.0, 0.8
    g = 9.81
    fz = p.mass * (g + 2.0 * (h_ref - obs[11]) - 2.5 * vz) / max(
        0.5, math.cos(phi) * math.cos(th))
    dpsi = (ref[2] - psi + math.pi) % (2 * math.pi) - math.pi
    mom = (p.ixx * (wn * wn * (ref[0] - phi) - 2 * z * wn * pr),
           p.iyy * (wn * wn * (ref[1] - th) - 2 * z * wn * qr),
           p.izz * (4.0 * dpsi - 4.0 * rr))
    thrust = prm[L.MIX_BASE:L.MIX_BASE + 16].reshape(4, 4) @ np.array([fz, *mom])
    act = np.zeros(7)
    act[0:4] = np.clip(np.sqrt(np.maximum(thrust, 0.0) / prm[L.KT]), p.omega_min, p.omega_max)
    return act


def _square(t: float, period: float) -> float:
    return 1.0 if (t / period) % 1.0 < 0.5 else -1.0


def _wing_control(model: GeneralAircraft, obs: NDArray[np.float64],
                  ref: tuple[float, float, float], t: float) -> NDArray[np.float64]:
    p, tr = model.params, model.trim
    _, _, _, phi, th, _, pr, qr, rr = obs[:9]
    va = math.sqrt(obs[0] ** 2 + obs[1] ** 2 + obs[2] ** 2)
    act = np.zeros(7)
    act[0] = min(p.omega_max, max(0.0, tr["omega"] + 40.0 * (p.v_cruise - va)))
    # Feedback plus direct surface square waves: inputs not fully explained by the
    # state, so moment derivatives stay separable (closed-loop identifiability).
    act[4] = 0.6 * (ref[0] - phi) - 0.08 * pr + 0.05 * _square(t, 0.9)
    act[5] = (tr["delta_e"] - 1.2 * (tr["alpha"] + ref[1] - th) + 0.15 * qr
              + 0.08 * _square(t, 0.7))
    act[6] = 0.2 * rr
    act[4:7] = np.clip(act[4:7], -p.delta_max, p.delta_max)
    return act


def fly(params: AircraftParams | str, kind: str, duration: float = 12.0, rate: float = 50.0,
        seed: int = 1, wind: WindConfig | None = None, noise: Noise | None = None,
        amp: float = 0.25, variant: int = 0) -> FlightLog:
    """A logged manoeuvre of the true aircraft ``params`` (see module docstring).

    Args:
        params: the true parameters (or a preset name).
        kind: ``quadrotor`` or ``fixedwing``.
        duration: flight time (s).
        rate: controller and log rate (Hz).
        seed: root seed (turbulence and sensor noise).
        wind: wind field of the true flight (default still air).
        noise: sensor noise (default :class:`Noise`; ``Noise(0, 0, 0, 0)`` = exact).
        amp: doublet amplitude (rad).
        variant: manoeuvre variant (0 = tuning, 1 = validation, ...).
    """
    model = GeneralAircraft(params, wind=wind, seed=seed)
    nz = noise or Noise()
    n = int(round(duration * rate)) + 1
    dt = 1.0 / rate
    state = model.initial_state(1)
    nodes = np.zeros(1, dtype=np.int64)
    h_ref = float(state[0, L.H])
    t = np.arange(n, dtype=np.float64) * dt
    obs = np.empty((n, 12))
    acts = np.empty((n, 7))
    for k in range(n):
        o = model.observe(state)[0]
        obs[k] = o
        ref = manoeuvre(t[k], kind, amp, variant)
        a = (_quad_control(model, o, ref, h_ref) if kind == "quadrotor"
             else _wing_control(model, o, ref, float(t[k])))
        acts[k] = a
        if k == 0:
            # Logs start in steady flight: actuators at their first command (replay.py).
            state[0, L.OM0:L.DR + 1] = a[0:7]
        if k + 1 < n:
            state = model.step_open_loop(state, a[None, :], dt, k + 1, nodes)
    rs = RandomStreams(seed).stream("tuning.sensor_noise")
    sd = np.array([nz.velocity] * 3 + [nz.angle] * 3 + [nz.rate] * 3 + [nz.position] * 3)
    obs = obs + sd * rs.normal(np.arange(n)[:, None], np.arange(12)[None, :])
    obs[:, 3] = np.angle(np.exp(1j * obs[:, 3]))
    obs[:, 5] = np.angle(np.exp(1j * obs[:, 5]))
    log_act = acts[:, 0:4] if kind == "quadrotor" else acts[:, [0, 4, 5, 6]]
    return FlightLog(kind=kind, t=t, act=log_act, obs=obs, source=f"synthetic:{kind}")
