"""Flight logs flown by JSBSim's ``minisgs`` sailplane (the ``jsbsim`` package's model).

``minisgs`` is a model glider of 8 ft span and 11 lb (2.44 m, 5.0 kg; no engine),
the scale of the paper's TALON. It glides at a trim speed held by a pitch-attitude
loop (speed error -> pitch reference, with integrators), a weak bank-angle hold and
a yaw damper, all at the log rate on JSBSim's state; on top of that loop every
surface gets an open-loop excitation, the paper's "high-manoeuvrability" inputs
(:func:`excitation`): doublets, 3-2-1-1 sequences and logarithmic frequency sweeps
on elevator and aileron. The excitation is what makes the moment derivatives
identifiable under the closed loop.

Logged control signals: the surface deflections JSBSim applied
(``fcs/left-aileron-pos-rad``, ``fcs/elevator-pos-rad``, ``fcs/rudder-pos-rad``;
minisgs has no actuator dynamics), held over each log interval, and ``omega0 = 0``
(no propeller). The logged state is JSBSim's, with the seeded sensor noise of
synth.py. The log starts after ``warmup`` seconds of unlogged trimmed glide.

Variants are different input programmes (0: the tuning programme; 1 and 2: held
out), so a validation log differs in inputs and, with another ``speed``, in trim.
:func:`glider_structure` reads the airframe's mass, inertia and geometry from
JSBSim (the "measured" structural parameters of the paper's Fig. 5).
Bad arguments raise ConfigError naming the command-line option.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sigma_des.core.rng import RandomStreams
from sigma_des.errors import ConfigError
from sigma_des.tuning.flightlog import FlightLog
from sigma_des.tuning.synth import Noise

__all__ = ["GLIDERS", "GlideSpec", "excitation", "fly_glider", "glider_structure"]

#: JSBSim gliders this generator flies.
GLIDERS: tuple[str, ...] = ("minisgs",)
#: Number of input programmes (``variant`` is in 0 .. VARIANTS - 1).
VARIANTS = 3
_FT = 0.3048
_SLUG = 14.593903
_FDM_RATE = 400.0
# Surface limits of minisgs (deg, its FCS): commands are normalised per sign.
_LIMITS = {"elevator": (-28.0, 23.0), "aileron": (-20.0, 15.0), "rudder": (-16.0, 16.0)}
_POS = {"elevator": "fcs/elevator-pos-rad", "aileron": "fcs/left-aileron-pos-rad",
        "rudder": "fcs/rudder-pos-rad"}
_CMD = {"elevator": "fcs/elevator-cmd-norm", "aileron": "fcs/aileron-cmd-norm",
        "rudder": "fcs/rudder-cmd-norm"}


@dataclass(frozen=True)
class GlideSpec:
    """One logged glide (every field is a ``sigma-des flightlog`` option).

    Attributes:
        aircraft: JSBSim glider (:data:`GLIDERS`).
        speed: trim airspeed (m/s), in [7, 16] (minisgs: CL from 0.5 to 0.1).
        speed_step: change of the trim speed halfway through the log (m/s), so one
            log holds two trims; ``speed + speed_step`` must be in [7, 16] too.
        duration: logged flight time (s), in [2, 600].
        rate: control and log rate (Hz), in [10, 400]; JSBSim integrates at a whole
            multiple of it, at least 400 Hz.
        variant: input programme, 0 .. VARIANTS - 1.
        seed: sensor-noise seed (>= 0).
        amp_e, amp_a: elevator / aileron excitation amplitude (rad), in [0, 0.2].
        altitude: start altitude (m), in [100, 3000].
        warmup: unlogged trimmed glide before the log (s), in [0, 60].
        noise: add the seeded sensor noise of synth.py.
    """

    aircraft: str = "minisgs"
    speed: float = 10.0
    speed_step: float = 0.0
    duration: float = 30.0
    rate: float = 50.0
    variant: int = 0
    seed: int = 1
    amp_e: float = 0.1
    amp_a: float = 0.15
    altitude: float = 300.0
    warmup: float = 8.0
    noise: bool = True

    def __post_init__(self) -> None:
        def req(ok: bool, key: str, why: str) -> None:
            if not ok:
                raise ConfigError(key, why)

        req(self.aircraft in GLIDERS, "--aircraft",
            f"must be one of {', '.join(GLIDERS)}, got {self.aircraft!r}")
        for key, v, lo, hi, unit in (("--speed", self.speed, 7.0, 16.0, " m/s"),
                                     ("--duration", self.duration, 2.0, 600.0, " s"),
                                     ("--rate", self.rate, 10.0, 400.0, " Hz"),
                                     ("--amp-e", self.amp_e, 0.0, 0.2, " rad"),
                                     ("--amp-a", self.amp_a, 0.0, 0.2, " rad"),
                                     ("--altitude", self.altitude, 100.0, 3000.0, " m"),
                                     ("--warmup", self.warmup, 0.0, 60.0, " s")):
            req(isinstance(v, int | float) and math.isfinite(v) and lo <= v <= hi, key,
                f"must be in [{lo:g}, {hi:g}]{unit}, got {v!r}")
        end = self.speed + self.speed_step
        req(math.isfinite(end) and 7.0 <= end <= 16.0, "--speed-step",
            f"--speed + --speed-step must be in [7, 16] m/s, got {end!r}")
        req(0 <= self.variant < VARIANTS, "--variant",
            f"must be in 0..{VARIANTS - 1}, got {self.variant}")
        req(0 <= self.seed < 2**63, "--seed", f"must be in 0..2^63-1, got {self.seed}")


def _doublet(t: float, t0: float, width: float) -> float:
    """+1 for ``width`` s from ``t0``, then -1 for ``width`` s, else 0."""
    x = (t - t0) / width
    return 1.0 if 0.0 <= x < 1.0 else (-1.0 if 1.0 <= x < 2.0 else 0.0)


def _3211(t: float, t0: float, unit: float) -> float:
    """The 3-2-1-1 sequence (+3, -2, +1, -1 units long) from ``t0``."""
    x = (t - t0) / unit
    for end, v in ((3.0, 1.0), (5.0, -1.0), (6.0, 1.0), (7.0, -1.0)):
        if 0.0 <= x < end:
            return v
    return 0.0


def _sweep(t: float, t0: float, length: float, f0: float, f1: float) -> float:
    """A logarithmic sine sweep from ``f0`` to ``f1`` Hz over ``length`` s (0 outside)."""
    x = t - t0
    if not 0.0 <= x < length:
        return 0.0
    k = math.log(f1 / f0) / length
    return math.sin(2.0 * math.pi * f0 * (math.exp(k * x) - 1.0) / k)


#: Input programmes: (axis, shape, start s, arguments); the programme repeats.
_PROGRAMMES: tuple[tuple[float, tuple[tuple[str, str, float, tuple[float, ...]], ...]], ...] = (
    (24.0, (("e", "doublet", 1.0, (0.5,)), ("a", "doublet", 3.0, (0.5,)),
            ("e", "3211", 5.0, (0.3,)), ("a", "3211", 8.0, (0.3,)),
            ("e", "sweep", 11.0, (6.0, 0.3, 3.0)), ("a", "sweep", 17.0, (6.0, 0.3, 3.0)))),
    (22.0, (("a", "doublet", 1.0, (0.35,)), ("e", "doublet", 1.4, (0.35,)),
            ("a", "3211", 3.5, (0.2,)), ("e", "3211", 5.5, (0.25,)),
            ("a", "sweep", 8.0, (6.0, 4.0, 0.5)), ("e", "sweep", 14.5, (6.0, 4.0, 0.5)),
            ("e", "doublet", 20.5, (0.6,)))),
    (20.0, (("e", "3211", 1.0, (0.4,)), ("a", "doublet", 4.5, (0.7,)),
            ("e", "sweep", 7.0, (5.0, 0.5, 2.5)), ("a", "sweep", 7.5, (5.0, 2.5, 0.5)),
            ("a", "3211", 13.5, (0.25,)), ("e", "doublet", 16.5, (0.3,)))),
)


def excitation(t: float, variant: int) -> tuple[float, float]:
    """Unit-amplitude elevator and aileron excitation at time ``t`` of programme ``variant``."""
    period, items = _PROGRAMMES[variant]
    tt = t % period
    out = {"e": 0.0, "a": 0.0}
    for axis, shape, t0, args in items:
        if shape == "doublet":
            v = _doublet(tt, t0, args[0])
        elif shape == "3211":
            v = _3211(tt, t0, args[0])
        else:
            v = 0.7 * _sweep(tt, t0, *args)
        out[axis] += v
    return out["e"], out["a"]


def _norm(surface: str, rad: float) -> float:
    """A deflection (rad) as minisgs's normalised command (its limits differ per sign)."""
    lo, hi = _LIMITS[surface]
    deg = math.degrees(rad)
    return max(-1.0, min(1.0, deg / hi if deg >= 0 else -deg / lo))


def _new_fdm(spec: GlideSpec) -> tuple[Any, Any, int]:
    """A JSBSim glider at the trim-speed guess, level, at ``spec.altitude``."""
    from sigma_des.agents.jsbsim_node import JSBSimModel

    m = JSBSimModel(spec.aircraft, fdm_rate=_FDM_RATE, altitude=spec.altitude,
                    v_cruise=spec.speed)
    nsub = max(1, math.ceil(_FDM_RATE / spec.rate - 1e-9))
    fdm = m._new()
    fdm.set_dt(1.0 / (spec.rate * nsub))
    m._init_from_row(fdm, m.initial_state(1)[0])
    return m, fdm, nsub


def glider_structure(aircraft: str = "minisgs") -> dict[str, float]:
    """Mass (kg), inertia (kg m^2), wing area, span, chord (m^2, m) and surface limit (rad).

    Read from JSBSim's model (``ixz`` in the Beard & McLain sign, as our ``ixz``).
    """
    _, fdm, _ = _new_fdm(GlideSpec(aircraft=aircraft))
    fdm.run()
    i = _SLUG * _FT * _FT
    return {"mass": fdm["inertia/mass-slugs"] * _SLUG,
            "ixx": fdm["inertia/ixx-slugs_ft2"] * i, "iyy": fdm["inertia/iyy-slugs_ft2"] * i,
            "izz": fdm["inertia/izz-slugs_ft2"] * i, "ixz": fdm["inertia/ixz-slugs_ft2"] * i,
            "s": fdm["metrics/Sw-sqft"] * _FT * _FT, "b": fdm["metrics/bw-ft"] * _FT,
            "c": fdm["metrics/cbarw-ft"] * _FT,
            "delta_max": math.radians(max(abs(v) for v in _LIMITS["elevator"]))}


def _pilot(o: np.ndarray, va: float, ints: list[float], spec: GlideSpec, t: float,
           dt: float, logged: bool) -> tuple[float, float, float]:
    """Elevator, aileron, rudder (rad): trim loops plus the excitation while logging."""
    phi, th, p, q, r = o[3], o[4], o[6], o[7], o[8]
    v_ref = spec.speed + (spec.speed_step if t >= 0.5 * spec.duration else 0.0)
    ints[0] = max(-20.0, min(20.0, ints[0] + dt * (va - v_ref)))
    th_ref = 0.04 * (va - v_ref) + 0.01 * ints[0] - 0.1
    e = th - th_ref
    ints[1] = max(-0.5, min(0.5, ints[1] + dt * e))
    ex_e, ex_a = excitation(t, spec.variant) if logged else (0.0, 0.0)
    de = 0.8 * e + 0.25 * q + 0.6 * ints[1] + spec.amp_e * ex_e
    da = -0.3 * phi - 0.02 * p + spec.amp_a * ex_a
    dr = 0.3 * r
    return de, da, dr


def fly_glider(spec: GlideSpec | None = None, noise: Noise | None = None) -> FlightLog:
    """A logged, excited glide of ``spec.aircraft`` (see module docstring)."""
    spec = spec or GlideSpec()
    m, fdm, nsub = _new_fdm(spec)
    dt = 1.0 / spec.rate
    n = int(round(spec.duration * spec.rate)) + 1
    warm = int(round(spec.warmup * spec.rate))
    obs = np.empty((n, 12))
    act = np.zeros((n, 4))
    ints = [0.0, 0.0]
    zero = np.zeros(4)
    for k in range(-warm, n):
        o = m._row(fdm, k * dt, zero)[:12]
        va = fdm["velocities/vt-fps"] * _FT
        de, da, dr = _pilot(o, va, ints, spec, k * dt, dt, k >= 0)
        for surf, v in (("elevator", de), ("aileron", da), ("rudder", dr)):
            fdm[_CMD[surf]] = _norm(surf, v)
        for _ in range(nsub):
            fdm.run()
        if k >= 0:
            obs[k] = o
            act[k, 1:4] = (fdm[_POS["aileron"]], fdm[_POS["elevator"]], fdm[_POS["rudder"]])
    if spec.noise:
        nz = noise or Noise()
        rs = RandomStreams(spec.seed).stream("tuning.sensor_noise")
        sd = np.array([nz.velocity] * 3 + [nz.angle] * 3 + [nz.rate] * 3 + [nz.position] * 3)
        obs = obs + sd * rs.normal(np.arange(n)[:, None], np.arange(12)[None, :])
        obs[:, 3] = np.angle(np.exp(1j * obs[:, 3]))
        obs[:, 5] = np.angle(np.exp(1j * obs[:, 5]))
    return FlightLog(kind="fixedwing", t=np.arange(n, dtype=np.float64) * dt, act=act, obs=obs,
                     source=f"jsbsim:{spec.aircraft} variant {spec.variant} at "
                     f"{spec.speed:g}" + (f"-{spec.speed + spec.speed_step:g}"
                                          if spec.speed_step else "") + " m/s")
