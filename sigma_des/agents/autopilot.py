"""Autopilots inside the dynamics model: guidance command -> actuator commands (numba).

Both autopilots read the common guidance command ``[v_cmd, chi_cmd, h_cmd,
phi_cmd]`` (see aircraft.py) and the true state (perfect state estimation: the
sensors of sensors.py model what an estimator would be fed, they do not close the
loop), run at every physics sub-step, and write seven actuator commands
``[omega_0..omega_3 (rad/s), delta_a, delta_e, delta_r (rad)]``. Their integrators
are state columns ``I0..I3``, so a checkpoint includes them.

Multirotor cascade (the classic PX4-style structure): horizontal velocity PI and
altitude P -> climb-rate PI give an acceleration demand; that becomes a thrust
magnitude and roll/pitch angles (heading = ``chi_cmd``); attitude P -> body-rate
setpoints; rate P -> moments; the inverse mixer turns (thrust, L, M, N) into rotor
thrusts and ``omega = sqrt(T / kT)``. ``phi_cmd`` (if not NaN) overrides the roll
angle. Integrators: I0/I1 north/east velocity error (m), I2 climb-rate error (m).

Fixed-wing successive loop closure (Beard & McLain 2012, ch. 6): course P ->
roll angle (or ``phi_cmd`` directly, the paper's formation law); roll PI + rate
damping -> aileron; altitude PI -> pitch angle around the trim pitch; pitch P +
rate damping -> elevator around the trim elevator; airspeed PI -> throttle around
the trim throttle, throttle -> motor speed ``omega = throttle * omega_max``;
rudder yaw damper about the coordinated-turn rate. Integrators: I0 roll error
(rad s), I1 altitude error (m s), I2 airspeed error (m).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sigma_des.agents import layout as L

__all__ = ["MULTIROTOR_GAINS", "FIXEDWING_GAINS", "multirotor_autopilot",
           "fixedwing_autopilot", "wrap_pi"]

#: Gain slots of the multirotor cascade (units in brackets in docs/AGENTS.md).
MULTIROTOR_GAINS: tuple[str, ...] = (
    "k_vel", "ki_vel", "k_alt", "vz_max", "k_vz", "ki_vz", "k_att", "k_rate",
    "k_yaw", "k_rate_yaw", "tilt_max", "a_max", "v_max", "yaw_rate_max",
)
#: Gain slots of the fixed-wing autopilot.
FIXEDWING_GAINS: tuple[str, ...] = (
    "k_chi", "phi_max", "k_phi", "k_p", "ki_phi", "k_alt", "ki_alt", "theta_max",
    "k_theta", "k_q", "k_v", "ki_v", "k_r", "v_min", "v_max", "alt_err_max",
)


@njit(cache=True, inline="always")
def wrap_pi(a: float) -> float:
    """Angle wrapped to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True, inline="always")
def _clip(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else (hi if v > hi else v)


@njit(cache=True, inline="always")
def multirotor_autopilot(x: np.ndarray, prm: np.ndarray, cmd: np.ndarray, phi: float,
                         theta: float, psi: float, vn: float, ve: float, vd: float,
                         g: float, h: float, act: np.ndarray) -> None:
    """Cascade controller: writes ``act`` and advances integrators I0..I2 of ``x``."""
    gb = L.GAIN_BASE
    kv, kiv, kh, vzmax = prm[gb], prm[gb + 1], prm[gb + 2], prm[gb + 3]
    kvz, kiz, katt, krate = prm[gb + 4], prm[gb + 5], prm[gb + 6], prm[gb + 7]
    kyaw, krr, tilt, amax = prm[gb + 8], prm[gb + 9], prm[gb + 10], prm[gb + 11]
    vmax, rmax = prm[gb + 12], prm[gb + 13]
    vc, chi, hc, phic = cmd[0], cmd[1], cmd[2], cmd[3]
    vc = _clip(vc, 0.0, vmax)
    # Velocity PI (north/east) -> horizontal acceleration demand.
    en, ee = vc * math.cos(chi) - vn, vc * math.sin(chi) - ve
    ilim = amax / kiv
    x[L.I0] = _clip(x[L.I0] + h * en, -ilim, ilim)
    x[L.I1] = _clip(x[L.I1] + h * ee, -ilim, ilim)
    an = kv * en + kiv * x[L.I0]
    ae = kv * ee + kiv * x[L.I1]
    amag = math.sqrt(an * an + ae * ae)
    if amag > amax:
        an *= amax / amag
        ae *= amax / amag
    # Altitude P -> climb-rate PI -> vertical acceleration demand (up).
    vzc = _clip(kh * (hc - x[L.H]), -vzmax, vzmax)
    ez = vzc + vd
    x[L.I2] = _clip(x[L.I2] + h * ez, -0.5 * g / kiz, 0.5 * g / kiz)
    gz = g + kvz * ez + kiz * x[L.I2]
    if gz < 0.3 * g:
        gz = 0.3 * g
    # Acceleration -> attitude in the heading frame (heading = commanded course).
    cp, sp = math.cos(psi), math.sin(psi)
    afwd = cp * an + sp * ae
    argt = -sp * an + cp * ae
    thc = _clip(-math.atan(afwd / gz), -tilt, tilt)
    if phic == phic:        # not NaN: roll override
        phc = _clip(phic, -tilt, tilt)
    else:
        phc = _clip(math.atan(argt * math.cos(thc) / gz), -tilt, tilt)
    thrust = prm[L.MASS] * gz / max(math.cos(phi) * math.cos(theta), 0.5)
    # Attitude P -> rate setpoints -> rate P -> moments.
    pc = katt * (phc - phi)
    qc = katt * (thc - theta)
    rc = _clip(kyaw * wrap_pi(chi - psi), -rmax, rmax)
    lm = prm[L.IXX] * krate * (pc - x[L.P])
    mm = prm[L.IYY] * krate * (qc - x[L.Q])
    nm = prm[L.IZZ] * krr * (rc - x[L.R])
    # Inverse mixer: rotor thrusts; omega from the static thrust constant.
    kt = prm[L.KT]
    mb = L.MIX_BASE
    wmin, wmax = prm[L.OMEGA_MIN], prm[L.OMEGA_MAX]
    for i in range(4):
        ti = (prm[mb + 4 * i] * thrust + prm[mb + 4 * i + 1] * lm
              + prm[mb + 4 * i + 2] * mm + prm[mb + 4 * i + 3] * nm)
        act[i] = _clip(math.sqrt(max(ti, 0.0) / kt), wmin, wmax)
    act[4] = 0.0
    act[5] = 0.0
    act[6] = 0.0


@njit(cache=True, inline="always")
def fixedwing_autopilot(x: np.ndarray, prm: np.ndarray, cmd: np.ndarray, phi: float,
                        theta: float, vn: float, ve: float, va: float, g: float,
                        h: float, act: np.ndarray) -> None:
    """Successive-loop-closure controller: writes ``act``, advances I0..I2 of ``x``."""
    gb = L.GAIN_BASE
    kchi, phimax, kphi, kp = prm[gb], prm[gb + 1], prm[gb + 2], prm[gb + 3]
    kiphi, kh, kih, thmax = prm[gb + 4], prm[gb + 5], prm[gb + 6], prm[gb + 7]
    kth, kq, kv, kiv = prm[gb + 8], prm[gb + 9], prm[gb + 10], prm[gb + 11]
    kr, vmin, vmax, hemax = prm[gb + 12], prm[gb + 13], prm[gb + 14], prm[gb + 15]
    dmax = prm[L.DELTA_MAX]
    vc, chic, hc, phic = cmd[0], cmd[1], cmd[2], cmd[3]
    vc = _clip(vc, vmin, vmax)
    # Lateral: course -> roll (unless the roll command is given) -> aileron.
    if phic == phic:
        phc = _clip(phic, -phimax, phimax)
    else:
        chi = math.atan2(ve, vn)
        phc = _clip(kchi * wrap_pi(chic - chi), -phimax, phimax)
    eph = phc - phi
    x[L.I0] = _clip(x[L.I0] + h * eph, -0.5, 0.5)
    act[4] = _clip(kphi * eph - kp * x[L.P] + kiphi * x[L.I0], -dmax, dmax)
    # Yaw damper about the coordinated-turn yaw rate.
    rss = g / max(va, 1.0) * math.sin(phi)
    act[6] = _clip(kr * (x[L.R] - rss), -dmax, dmax)
    # Longitudinal: altitude PI -> pitch -> elevator; airspeed PI -> throttle.
    eh = _clip(hc - x[L.H], -hemax, hemax)
    if abs(eh) < 5.0:
        # Integrate only near the target altitude: no wind-up during long climbs.
        x[L.I1] = _clip(x[L.I1] + h * eh, -thmax / kih, thmax / kih)
    thc = _clip(prm[L.TRIM_THETA] + kh * eh + kih * x[L.I1], -thmax, thmax)
    act[5] = _clip(prm[L.TRIM_DE] - kth * (thc - theta) + kq * x[L.Q], -dmax, dmax)
    ev = vc - va
    x[L.I2] = _clip(x[L.I2] + h * ev, -1.0 / kiv, 1.0 / kiv)
    thr = _clip(prm[L.TRIM_THROTTLE] + kv * ev + kiv * x[L.I2], 0.0, 1.0)
    act[0] = thr * prm[L.OMEGA_MAX]
    act[1] = 0.0
    act[2] = 0.0
    act[3] = 0.0
