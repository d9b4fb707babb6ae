"""Cross-model flight logs flown by JSBSim's F450 quadrotor (the ``jsbsim`` package's model).

The F450 flies the same attitude manoeuvre as synth.py (doublets in roll and
pitch, a yaw sweep) under JSBSim's own flight control system: our attitude /
altitude loop at the log rate writes the normalised stick and throttle
commands, the F450's rate SCAS (``fcs/ScasEngage``) and mixer turn them into
four motor commands, and JSBSim's electric motors and propellers
(DJI E305 + 9450) produce thrust and torque. The logged control signals are
the four propeller speeds (``propulsion/engine[i]/propeller-rpm``, in rad/s,
averaged over each log interval — the sample-and-hold value that best
represents them), in our rotor order (JSBSim engines 0–3 are front-right,
aft-left, front-left, aft-right, the same order and spin senses as our
preset). The log starts after 3 s of hover (the motors spin up from rest
in JSBSim's initial condition; a log must start in steady flight). The
logged state is JSBSim's, with the same seeded sensor noise as synth.py.
Fitting our model to such a log tests the tuning across model
structures: JSBSim's propeller tables, motor model and frame aerodynamics are
not ours.
"""

from __future__ import annotations

import math

import numpy as np

from sigma_des.agents.jsbsim_node import JSBSimModel
from sigma_des.core.rng import RandomStreams
from sigma_des.tuning.flightlog import FlightLog
from sigma_des.tuning.synth import Noise, manoeuvre

__all__ = ["fly_f450"]

_RPM = 2 * math.pi / 60
#: Unlogged hover before the log starts: JSBSim's motors start at rest (s).
_WARMUP = 3.0


def _clip(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else (hi if v > hi else v)


def fly_f450(duration: float = 10.0, rate: float = 50.0, seed: int = 1, amp: float = 0.25,
             variant: int = 0, noise: Noise | None = None) -> FlightLog:
    """A logged manoeuvre of JSBSim's F450 (see module docstring).

    Args:
        duration: flight time (s).
        rate: controller and log rate (Hz); JSBSim integrates at 400 Hz.
        seed: sensor-noise seed.
        amp: roll / pitch doublet amplitude (rad).
        variant: manoeuvre variant (0 tuning, 1 validation).
        noise: sensor noise (default :class:`~sigma_des.tuning.synth.Noise`).
    """
    m = JSBSimModel("F450", fdm_rate=400.0)
    fdm = m._new()
    row = m.initial_state(1)[0]
    m._init_from_row(fdm, row)
    nsub = max(1, int(round(400.0 / rate)))
    dt = 1.0 / rate
    n = int(round(duration * rate)) + 1
    obs = np.empty((n, 12))
    act = np.empty((n, 4))
    ints = np.zeros(4)
    h_ref = float(row[11])
    warm = int(round(_WARMUP * rate))
    for k in range(-warm, n):
        t = k * dt
        o = m._row(fdm, t, ints)[:12]
        phi_r, th_r, psi_r = (manoeuvre(t, "quadrotor", amp, variant) if k >= 0
                              else (0.0, 0.0, 0.0))
        vup = -fdm["velocities/v-down-fps"] * 0.3048
        ez = _clip(1.0 * (h_ref - o[11]), -2.0, 2.0) - vup
        ints[2] = _clip(ints[2] + dt * ez, -2.0, 2.0)
        fdm["fcs/throttle-cmd-norm"] = _clip(m.hover_throttle + 0.15 * ez + 0.1 * ints[2], 0, 1)
        fdm["fcs/aileron-cmd-norm"] = _clip(3.0 * (phi_r - o[3]) / 0.75, -1, 1)
        fdm["fcs/elevator-cmd-norm"] = _clip(3.0 * (th_r - o[4]) / 0.75, -1, 1)
        dpsi = (psi_r - o[5] + math.pi) % (2 * math.pi) - math.pi
        fdm["fcs/rudder-cmd-norm"] = _clip(1.0 * dpsi / 0.75, -1, 1)
        acc = np.zeros(4)
        for _ in range(nsub):
            fdm.run()
            for i in range(4):
                acc[i] += fdm[f"propulsion/engine[{i}]/propeller-rpm"]
        if k >= 0:
            obs[k] = o
            act[k] = acc / nsub * _RPM
    nz = noise or Noise()
    rs = RandomStreams(seed).stream("tuning.sensor_noise")
    sd = np.array([nz.velocity] * 3 + [nz.angle] * 3 + [nz.rate] * 3 + [nz.position] * 3)
    obs = obs + sd * rs.normal(np.arange(n)[:, None], np.arange(12)[None, :])
    obs[:, 3] = np.angle(np.exp(1j * obs[:, 3]))
    obs[:, 5] = np.angle(np.exp(1j * obs[:, 5]))
    return FlightLog(kind="quadrotor", t=np.arange(n, dtype=np.float64) * dt, act=act, obs=obs,
                     source=f"jsbsim:F450 variant {variant}")
