"""Autopilots inside the dynamics model: guidance command -> actuator commands (numba).

Both autopilots read the common guidance command ``[v_cmd, chi_cmd, h_cmd,
phi_cmd]`` (see aircraft.py) and the true state (perfect state estimation: the
sensors of sensors.py model what an estimator would be fed, they do not close the
loop), run their inner loops at every physics sub-step (slow outer parts — yaw,
course, command geometry — once per frame step), and write seven actuator commands
``[omega_0..omega_3 (rad/s), delta_a, delta_e, delta_r (rad)]``. Their integrators
are state columns ``I0..I3``, so a checkpoint includes them.

Multirotor cascade (the classic PX4-style structure): horizontal velocity PI and
altitude P -> climb-rate PI give an acceleration demand; that becomes a thrust
magnitude and a thrust direction (tilt-limited; heading = ``chi_cmd``);
geometric attitude P (body z axis -> demanded direction) -> body-rate
setpoints; rate P -> moments; the inverse mixer turns (thrust, L, M, N) into rotor
thrusts and ``omega = sqrt(T / kT)``. ``phi_cmd`` (if not NaN) sets the lateral acceleration to
``g tan(phi_cmd)`` (the bank angle of a coordinated turn).
Integrators: I0/I1 north/east velocity error (m), I2 climb-rate error (m).

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
from sigma_des.agents.approx import asin_fast, atan2_fast, sqrt, wrap_pi
from sigma_des.agents.rigid_body import to_body

__all__ = ["MULTIROTOR_GAINS", "FIXEDWING_GAINS", "multirotor_prepare", "multirotor_autopilot",
           "fixedwing_prepare", "fixedwing_autopilot"]

#: Gain slots of the multirotor cascade (units in brackets in docs/concepts/aircraft.md).
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
def _clip(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else (hi if v > hi else v)


@njit(cache=True, inline="always")
def multirotor_prepare(prm: np.ndarray, cmd: tuple, rm: tuple, heading: tuple,
                       tan_tilt: float, pre: np.ndarray) -> None:
    """Per-frame part of the cascade: velocity vector, yaw-rate and roll-override set-points.

    The yaw loop and the command geometry change slowly, so they are evaluated
    once per frame step and held over its sub-steps (saves trigonometry).

    Args:
        prm: aircraft parameter vector.
        cmd: the resolved guidance command (no NaN in slots 0-2).
        rm: rotation matrix.
        heading: ``(cos, sin)`` of the heading (``(1, 0)`` when pointing straight up).
        tan_tilt: ``tan`` of the tilt limit (a constant of the aircraft).
        pre: the 8 set-points (written).
    """
    gb = L.GAIN_BASE
    tilt, vmax, rmax = prm[gb + 10], prm[gb + 12], prm[gb + 13]
    vc = _clip(cmd[0], 0.0, vmax)
    chi = cmd[1]
    pre[0] = vc * math.cos(chi)
    pre[1] = vc * math.sin(chi)
    pre[2] = cmd[2]
    psi = atan2_fast(rm[3], rm[0])
    pre[3] = _clip(prm[gb + 8] * wrap_pi(chi - psi), -rmax, rmax)
    pre[4] = math.tan(_clip(cmd[3], -tilt, tilt)) if cmd[3] == cmd[3] else math.nan
    pre[5], pre[6] = heading
    pre[7] = tan_tilt


@njit(cache=True, inline="always")
def _mixer_row(prm: np.ndarray, i: int) -> tuple[float, float, float, float]:
    """Row ``i`` of the inverse mixer: (thrust, L, M, N) -> rotor ``i``'s thrust."""
    mb = L.MIX_BASE + 4 * i
    return prm[mb], prm[mb + 1], prm[mb + 2], prm[mb + 3]


@njit(cache=True, inline="always")
def _rotor_speed(row: tuple, thrust: float, lm: float, mm: float, nm: float, kt: float,
                 wmin: float, wmax: float) -> float:
    """Rotor speed of mixer ``row`` from the static thrust constant ``kt``, clipped."""
    ti = row[0] * thrust + row[1] * lm + row[2] * mm + row[3] * nm
    return _clip(sqrt(max(ti, 0.0) / kt), wmin, wmax)


@njit(cache=True, inline="always")
def multirotor_autopilot(prm: np.ndarray, pre: tuple, rm: tuple, vn: float, ve: float,
                         vd: float, g: float, h: float, hgt: float, p: float, q: float,
                         r: float, i0: float, i1: float, i2: float) -> tuple:
    """Cascade controller sub-step (a pure function of scalars).

    The attitude loop is geometric: the error is the rotation taking the body z
    axis to the demanded thrust direction, expressed in body axes — no Euler angles.

    Args:
        prm: aircraft parameter vector.
        pre: the 8 set-points of :func:`multirotor_prepare`.
        rm: rotation matrix; ``vn, ve, vd``: NED ground velocity (m/s).
        g: gravity (m/s^2); ``h``: sub-step (s); ``hgt``: altitude (m).
        p, q, r: body rates (rad/s); ``i0, i1, i2``: integrator states.

    Returns:
        New ``(i0, i1, i2)`` and the seven actuator commands (ACTUATOR_NAMES).
    """
    gb = L.GAIN_BASE
    kv, kiv, kh, vzmax = prm[gb], prm[gb + 1], prm[gb + 2], prm[gb + 3]
    kvz, kiz, katt, krate = prm[gb + 4], prm[gb + 5], prm[gb + 6], prm[gb + 7]
    krr, amax = prm[gb + 9], prm[gb + 11]
    # Every parameter is read before the first branch (see aero.py).
    mass, ixx, iyy, izz = prm[L.MASS], prm[L.IXX], prm[L.IYY], prm[L.IZZ]
    kt, wmin, wmax = prm[L.KT], prm[L.OMEGA_MIN], prm[L.OMEGA_MAX]
    m0, m1, m2, m3 = _mixer_row(prm, 0), _mixer_row(prm, 1), _mixer_row(prm, 2), _mixer_row(prm, 3)
    # Velocity PI (north/east) -> horizontal acceleration demand.
    en, ee = pre[0] - vn, pre[1] - ve
    ilim = amax / kiv
    i0 = _clip(i0 + h * en, -ilim, ilim)
    i1 = _clip(i1 + h * ee, -ilim, ilim)
    an = kv * en + kiv * i0
    ae = kv * ee + kiv * i1
    amag = sqrt(an * an + ae * ae)
    if amag > amax:
        an *= amax / amag
        ae *= amax / amag
    # Altitude P -> climb-rate PI -> vertical acceleration demand (up).
    vzc = _clip(kh * (pre[2] - hgt), -vzmax, vzmax)
    ez = vzc + vd
    i2 = _clip(i2 + h * ez, -0.5 * g / kiz, 0.5 * g / kiz)
    gz = g + kvz * ez + kiz * i2
    if gz < 0.3 * g:
        gz = 0.3 * g
    if pre[4] == pre[4]:
        # Roll override: keep the forward demand, set the lateral one to g tan(phi).
        ch, sh = pre[5], pre[6]
        afwd = ch * an + sh * ae
        argt = gz * pre[4]
        an, ae = ch * afwd - sh * argt, sh * afwd + ch * argt
    lim = gz * pre[7]
    amag = sqrt(an * an + ae * ae)
    if amag > lim:
        an *= lim / amag
        ae *= lim / amag
    # Demanded thrust direction (NED, pointing "down" like body z) vs body z.
    fn = sqrt(an * an + ae * ae + gz * gz)
    zdx, zdy, zdz = -an / fn, -ae / fn, gz / fn
    zbx, zby, zbz = rm[2], rm[5], rm[8]
    ex, ey, ez_ = to_body(rm, zby * zdz - zbz * zdy, zbz * zdx - zbx * zdz, zbx * zdy - zby * zdx)
    thrust = mass * max(gz * zbz - an * zbx - ae * zby, 0.0)
    # Attitude P -> rate set-points -> rate P -> moments; inverse mixer -> rotor speeds.
    lm = ixx * krate * (katt * ex - p)
    mm = iyy * krate * (katt * ey - q)
    nm = izz * krr * (pre[3] - r)
    return (i0, i1, i2, _rotor_speed(m0, thrust, lm, mm, nm, kt, wmin, wmax),
            _rotor_speed(m1, thrust, lm, mm, nm, kt, wmin, wmax),
            _rotor_speed(m2, thrust, lm, mm, nm, kt, wmin, wmax),
            _rotor_speed(m3, thrust, lm, mm, nm, kt, wmin, wmax), 0.0, 0.0, 0.0)


@njit(cache=True, inline="always")
def fixedwing_prepare(prm: np.ndarray, cmd: tuple, vn: float, ve: float,
                      pre: np.ndarray) -> None:
    """Per-frame part: airspeed and altitude set-points, course loop -> roll set-point."""
    gb = L.GAIN_BASE
    phimax = prm[gb + 1]
    pre[0] = _clip(cmd[0], prm[gb + 13], prm[gb + 14])
    pre[2] = cmd[2]
    if cmd[3] == cmd[3]:
        pre[3] = _clip(cmd[3], -phimax, phimax)
    else:
        chi = atan2_fast(ve, vn)
        pre[3] = _clip(prm[gb] * wrap_pi(cmd[1] - chi), -phimax, phimax)


@njit(cache=True, inline="always")
def fixedwing_autopilot(prm: np.ndarray, pre: tuple, rm: tuple, va: float, g: float,
                        h: float, hgt: float, p: float, q: float, r: float, i0: float,
                        i1: float, i2: float) -> tuple:
    """Successive-loop-closure sub-step (a pure function of scalars).

    Args:
        prm: aircraft parameter vector.
        pre: the set-points of :func:`fixedwing_prepare` (slots 0, 2, 3 are read).
        rm: rotation matrix; ``va``: airspeed (m/s); ``g``: gravity (m/s^2).
        h: sub-step (s); ``hgt``: altitude (m); ``p, q, r``: body rates (rad/s).
        i0, i1, i2: integrator states.

    Returns:
        New ``(i0, i1, i2)`` and the seven actuator commands (ACTUATOR_NAMES).
    """
    gb = L.GAIN_BASE
    kphi, kp = prm[gb + 2], prm[gb + 3]
    kiphi, kh, kih, thmax = prm[gb + 4], prm[gb + 5], prm[gb + 6], prm[gb + 7]
    kth, kq, kv, kiv = prm[gb + 8], prm[gb + 9], prm[gb + 10], prm[gb + 11]
    kr, hemax = prm[gb + 12], prm[gb + 15]
    dmax = prm[L.DELTA_MAX]
    # Every parameter is read before the first branch (see aero.py).
    trim_theta, trim_de, trim_thr = prm[L.TRIM_THETA], prm[L.TRIM_DE], prm[L.TRIM_THROTTLE]
    wmax = prm[L.OMEGA_MAX]
    phi = atan2_fast(rm[7], rm[8])
    theta = asin_fast(-rm[6])
    # Lateral: roll PI + rate damping -> aileron.
    eph = pre[3] - phi
    i0 = _clip(i0 + h * eph, -0.5, 0.5)
    da = _clip(kphi * eph - kp * p + kiphi * i0, -dmax, dmax)
    # Yaw damper about the coordinated-turn yaw rate g sin(phi) / V.
    rss = g / max(va, 1.0) * rm[7]
    dr = _clip(kr * (r - rss), -dmax, dmax)
    # Longitudinal: altitude PI -> pitch -> elevator; airspeed PI -> throttle.
    eh = _clip(pre[2] - hgt, -hemax, hemax)
    if abs(eh) < 5.0:
        # Integrate only near the target altitude: no wind-up during long climbs.
        i1 = _clip(i1 + h * eh, -thmax / kih, thmax / kih)
    thc = _clip(trim_theta + kh * eh + kih * i1, -thmax, thmax)
    de = _clip(trim_de - kth * (thc - theta) + kq * q, -dmax, dmax)
    ev = pre[0] - va
    i2 = _clip(i2 + h * ev, -1.0 / kiv, 1.0 / kiv)
    thr = _clip(trim_thr + kv * ev + kiv * i2, 0.0, 1.0)
    return i0, i1, i2, thr * wmax, 0.0, 0.0, 0.0, da, de, dr
