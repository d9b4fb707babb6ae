"""Validated aircraft parameter sets and their packing into the kernel's flat vector.

A :class:`AircraftParams` is everything that defines one aircraft type: rigid
body, rotors (geometry + blade-element coefficients + motor lag), aerodynamic
coefficients, actuators, autopilot gains and the sub-step bound. Presets live in
presets.py; users may build their own or ``dataclasses.replace`` a preset. Every
invalid value raises :class:`~sigma_des.errors.ConfigError` naming the field.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import NDArray

from sigma_des.agents import layout as L
from sigma_des.agents.autopilot import FIXEDWING_GAINS, MULTIROTOR_GAINS
from sigma_des.agents.rotor import hover_inflow
from sigma_des.errors import ConfigError

__all__ = ["RotorSpec", "AeroCoeffs", "AircraftParams", "AUTOPILOTS", "PARAM_RANGES",
           "check_range"]

#: Plausible range of every number of an aircraft, from a 50 g micro drone to a
#: light aircraft, with its unit: ``name -> (low, high, unit)``; names in
#: :data:`_POSITIVE` must also be > 0 (the low end is open). ``aero.*`` holds for
#: every aerodynamic coefficient, ``gains.*`` for every autopilot gain. A value
#: outside (``ixx = 1e300``) is a typo or a unit slip, never an aircraft.
PARAM_RANGES: dict[str, tuple[float, float, str]] = {
    "mass": (0.0, 1e4, "kg"),
    "ixx": (0.0, 1e5, "kg m^2"),
    "iyy": (0.0, 1e5, "kg m^2"),
    "izz": (0.0, 1e5, "kg m^2"),
    "ixz": (-1e5, 1e5, "kg m^2"),
    "rotor_radius": (0.0, 10.0, "m"),
    "rotor_solidity": (0.0, 1.0, ""),
    "rotor_lift_slope": (0.0, 10.0, "1/rad"),
    "rotor_cd0": (0.0, 1.0, ""),
    "tau_motor": (0.0, 10.0, "s"),
    "omega_max": (0.0, 1e5, "rad/s"),
    "omega_min": (0.0, 1e5, "rad/s"),
    "tau_servo": (0.0, 10.0, "s"),
    "delta_max": (0.0, math.pi / 2, "rad"),
    "v_cruise": (0.0, 400.0, "m/s"),
    "altitude": (-1e3, 1e5, "m"),
    "spacing": (0.0, 1e4, "m"),
    "max_substep": (0.0, 1.0, "s"),
    "aero.s": (0.0, 1e3, "m^2"),
    "aero.b": (0.0, 1e3, "m"),
    "aero.c": (0.0, 1e3, "m"),
    "aero.*": (-1e3, 1e3, ""),
    "gains.*": (-1e6, 1e6, ""),
}
_POSITIVE = ("mass", "ixx", "iyy", "izz", "rotor_radius", "rotor_solidity",
             "rotor_lift_slope", "tau_motor", "omega_max", "tau_servo", "delta_max",
             "max_substep", "spacing")


def check_range(name: str, value: float) -> str | None:
    """Why ``value`` is outside the :data:`PARAM_RANGES` entry of ``name`` (``None``
    if inside, or if ``name`` has no entry); ``name`` is e.g. ``ixx``, ``aero.cl_a``."""
    group = name.split(".")[0] + ".*"
    entry = PARAM_RANGES.get(name) or PARAM_RANGES.get(group)
    if entry is None:
        return None
    lo, hi, unit = entry
    positive = name in _POSITIVE
    if (value > lo if positive else value >= lo) and value <= hi:
        return None
    unit = f" {unit}" if unit else ""
    return f"must be in {'(' if positive else '['}{lo:g}, {hi:g}]{unit}, got {value!r}"


#: Autopilot kinds and their kernel codes.
AUTOPILOTS: dict[str, int] = {"none": 0, "multirotor": 1, "fixedwing": 2}


@dataclass(frozen=True)
class RotorSpec:
    """One rotor: hub position and thrust axis in body axes, spin sign.

    Attributes:
        pos: hub position relative to the CG, body axes (m).
        axis: unit thrust direction, body axes ((0, 0, -1) = up for a multirotor).
        spin: +1 if the rotor's angular velocity points along ``axis``, else -1.
    """

    pos: tuple[float, float, float]
    axis: tuple[float, float, float]
    spin: float


@dataclass(frozen=True)
class AeroCoeffs:
    """Aerodynamic reference geometry and non-dimensional coefficients (aero.py).

    ``b == 0`` means a bluff body with drag ``CD0`` only (multirotor frame).
    Coefficient names follow Beard & McLain: ``cl_*`` lift, ``cd_*`` drag,
    ``cy_*`` side force, ``cll_*`` roll, ``cm_*`` pitch, ``cn_*`` yaw moment;
    suffixes ``a`` alpha, ``b`` beta, ``p``/``q``/``r`` non-dimensional rates,
    ``da``/``de``/``dr`` surface deflections (per rad). ``cd_k`` is the induced
    drag factor ``1 / (pi e AR)``.
    """

    s: float = 0.0
    b: float = 0.0
    c: float = 0.0
    cl_0: float = 0.0
    cl_a: float = 0.0
    cl_q: float = 0.0
    cl_de: float = 0.0
    cl_max: float = 1.2
    cd_0: float = 0.0
    cd_k: float = 0.0
    cd_de: float = 0.0
    cy_b: float = 0.0
    cy_p: float = 0.0
    cy_r: float = 0.0
    cy_da: float = 0.0
    cy_dr: float = 0.0
    cll_b: float = 0.0
    cll_p: float = 0.0
    cll_r: float = 0.0
    cll_da: float = 0.0
    cll_dr: float = 0.0
    cm_0: float = 0.0
    cm_a: float = 0.0
    cm_q: float = 0.0
    cm_de: float = 0.0
    cn_b: float = 0.0
    cn_p: float = 0.0
    cn_r: float = 0.0
    cn_da: float = 0.0
    cn_dr: float = 0.0


@dataclass(frozen=True)
class AircraftParams:
    """One aircraft type (see presets.py for documented examples).

    Attributes:
        name: preset name (used in error messages).
        mass: take-off mass (kg).
        ixx, iyy, izz, ixz: inertia about body axes (kg m^2).
        rotors: rotor geometry (1..4 rotors).
        rotor_radius: blade radius (m).
        rotor_solidity: blade area / disc area.
        rotor_lift_slope: blade section lift-curve slope (1/rad).
        rotor_pitch: collective pitch at 3/4 radius (rad).
        rotor_cd0: blade section profile drag coefficient.
        tau_motor: motor + rotor first-order speed lag (s).
        omega_max, omega_min: rotor speed limits (rad/s).
        aero: aerodynamic coefficients.
        tau_servo: control-surface servo lag (s).
        delta_max: surface deflection limit (rad).
        autopilot: ``none``, ``multirotor`` or ``fixedwing``.
        gains: autopilot gains (names: autopilot.MULTIROTOR_GAINS / FIXEDWING_GAINS).
        v_cruise: default speed command and fixed-wing trim airspeed (m/s).
        altitude: initial altitude of :meth:`GeneralAircraft.initial_state` (m).
        spacing: initial grid spacing (m).
        max_substep: largest internal integration step (s).
    """

    name: str
    mass: float
    ixx: float
    iyy: float
    izz: float
    ixz: float
    rotors: tuple[RotorSpec, ...]
    rotor_radius: float
    rotor_solidity: float
    rotor_lift_slope: float
    rotor_pitch: float
    rotor_cd0: float
    tau_motor: float
    omega_max: float
    omega_min: float
    aero: AeroCoeffs = field(default_factory=AeroCoeffs)
    tau_servo: float = 0.02
    delta_max: float = 0.4
    autopilot: str = "none"
    gains: dict[str, float] = field(default_factory=dict)
    v_cruise: float = 0.0
    altitude: float = 100.0
    spacing: float = 10.0
    max_substep: float = 0.005

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ConfigError:
            return ConfigError(f"{self.name}.{name}", why)

        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, float | int) and not isinstance(v, bool) and not math.isfinite(v):
                raise bad(f.name, f"must be finite, got {v}")
        for name in _POSITIVE:
            if not getattr(self, name) > 0:
                raise bad(name, f"must be > 0, got {getattr(self, name)}")
        self._check_ranges(bad)
        if not 0 <= self.omega_min < self.omega_max:
            raise bad("omega_min",
                      f"must be in [0, omega_max={self.omega_max}), got {self.omega_min}")
        if not 0 <= self.rotor_pitch < 0.7:
            raise bad("rotor_pitch", f"must be in [0, 0.7) rad, got {self.rotor_pitch}")
        if self.rotor_cd0 < 0:
            raise bad("rotor_cd0", f"must be >= 0, got {self.rotor_cd0}")
        if not 1 <= len(self.rotors) <= L.MAX_ROTORS:
            raise bad("rotors", f"must hold 1..{L.MAX_ROTORS} rotors, got {len(self.rotors)}")
        if self.ixz * self.ixz >= self.ixx * self.izz:
            raise bad("ixz", "must satisfy ixz^2 < ixx * izz (positive-definite inertia)")
        if self.autopilot not in AUTOPILOTS:
            raise bad("autopilot", f"must be one of {sorted(AUTOPILOTS)}, got {self.autopilot!r}")
        if self.autopilot == "multirotor" and len(self.rotors) != 4:
            raise bad("rotors", "the multirotor autopilot needs exactly 4 rotors")
        names = {"multirotor": MULTIROTOR_GAINS, "fixedwing": FIXEDWING_GAINS}.get(
            self.autopilot, ())
        unknown = sorted(set(self.gains) - set(names))
        if unknown:
            raise bad("gains", f"unknown gain(s) {unknown}; allowed: {list(names)}")
        missing = [g for g in names if g not in self.gains]
        if missing:
            raise bad("gains", f"missing gain(s) {missing}")
        if self.aero.s < 0 or self.aero.b < 0 or self.aero.c < 0:
            raise bad("aero", "reference area, span and chord must be >= 0")

    def _check_ranges(self, bad: Callable[[str, str], ConfigError]) -> None:
        values = [(f.name, getattr(self, f.name)) for f in fields(self)]
        values += [(f"aero.{f.name}", getattr(self.aero, f.name)) for f in fields(self.aero)]
        values += [(f"gains.{k}", v) for k, v in self.gains.items()]
        for name, v in values:
            if isinstance(v, float | int) and not isinstance(v, bool):
                why = check_range(name, float(v))
                if why:
                    raise bad(name, why)

    @property
    def hover_inflow(self) -> tuple[float, float]:
        """Static inflow ratio and thrust coefficient of the rotors (rotor.py)."""
        return hover_inflow(self.rotor_solidity, self.rotor_lift_slope, self.rotor_pitch)

    def to_array(self) -> NDArray[np.float64]:
        """The kernel parameter vector (environment, mixer and trim slots left zero)."""
        p = np.zeros(L.PARAM_DIM)
        p[L.MASS], p[L.IXX], p[L.IYY], p[L.IZZ], p[L.IXZ] = (
            self.mass, self.ixx, self.iyy, self.izz, self.ixz)
        p[L.NROT] = len(self.rotors)
        lam_h, ct = self.hover_inflow
        p[L.ROT_R], p[L.ROT_SIGMA], p[L.ROT_A] = (
            self.rotor_radius, self.rotor_solidity, self.rotor_lift_slope)
        p[L.ROT_THETA], p[L.ROT_CD0], p[L.ROT_LAMBDA_H] = self.rotor_pitch, self.rotor_cd0, lam_h
        cq = self.rotor_solidity * self.rotor_cd0 / 8.0 + lam_h * ct
        r = self.rotor_radius
        # Sea-level static thrust/torque constants T = kT w^2, Q = kQ w^2 (mixer only).
        p[L.KT] = ct * 1.225 * math.pi * r ** 4
        p[L.KQ] = cq * 1.225 * math.pi * r ** 5
        p[L.TAU_MOTOR], p[L.OMEGA_MAX], p[L.OMEGA_MIN] = (
            self.tau_motor, self.omega_max, self.omega_min)
        for i, rot in enumerate(self.rotors):
            k = L.ROTOR_BASE + L.ROTOR_STRIDE * i
            ax = np.asarray(rot.axis, dtype=float)
            ax = ax / np.linalg.norm(ax)
            p[k:k + 3] = rot.pos
            p[k + 3:k + 6] = ax
            p[k + 6] = 1.0 if rot.spin >= 0 else -1.0
        a = self.aero
        p[L.AERO_S:L.DELTA_MAX + 1] = (
            a.s, a.b, a.c, a.cl_0, a.cl_a, a.cl_q, a.cl_de, a.cl_max, a.cd_0, a.cd_k, a.cd_de,
            a.cy_b, a.cy_p, a.cy_r, a.cy_da, a.cy_dr, a.cll_b, a.cll_p, a.cll_r, a.cll_da,
            a.cll_dr, a.cm_0, a.cm_a, a.cm_q, a.cm_de, a.cn_b, a.cn_p, a.cn_r, a.cn_da,
            a.cn_dr, self.tau_servo, self.delta_max)
        p[L.AP_KIND] = AUTOPILOTS[self.autopilot]
        names = {"multirotor": MULTIROTOR_GAINS, "fixedwing": FIXEDWING_GAINS}.get(
            self.autopilot, ())
        for j, g in enumerate(names):
            p[L.GAIN_BASE + j] = self.gains[g]
        p[L.ENV_SUBSTEP] = self.max_substep
        p[L.ENV_HREF] = 10.0
        return p
