"""Documented aircraft presets: an F450-class quadrotor and a TALON-class fixed wing.

Every number carries its source or derivation. Where a source gives a propeller
in the APC/JSBSim convention (``CT = T / (rho n^2 D^4)``, ``CP = P / (rho n^3
D^5)``, n in rev/s), :func:`fit_rotor` converts it to the rotor convention of
rotor.py (``T = CT rho pi R^2 (omega R)^2``; factor ``4 / pi^3`` for thrust and
``4 / pi^4`` for torque) and solves the blade-element model for the collective
pitch and profile drag that reproduce the static values exactly.
"""

from __future__ import annotations

import math

from sigma_des.agents.params import AeroCoeffs, AircraftParams, RotorSpec
from sigma_des.errors import ConfigError

__all__ = ["PRESETS", "fit_rotor", "quadrotor_f450", "fixedwing_talon", "preset"]


def fit_rotor(ct_apc: float, cp_apc: float, sigma: float, a: float) -> tuple[float, float]:
    """Collective pitch (rad) and profile drag coefficient matching static CT and CP.

    Args:
        ct_apc: static thrust coefficient, APC convention.
        cp_apc: static power coefficient, APC convention.
        sigma: rotor solidity.
        a: blade lift-curve slope (1/rad).
    """
    ct = ct_apc * 4.0 / math.pi ** 3
    cq = cp_apc * 4.0 / math.pi ** 4
    lam = math.sqrt(ct / 2.0)                  # momentum theory, hover
    theta = 3.0 * (ct / (0.5 * sigma * a) + lam / 2.0)
    cd0 = 8.0 * (cq - lam * ct) / sigma
    return theta, cd0


def quadrotor_f450() -> AircraftParams:
    """DJI F450-class quadrotor, numbers aligned with JSBSim's shipped ``F450`` model.

    Aligning with the JSBSim model (aircraft/F450 in the ``jsbsim`` package) makes
    the ``jsbsim:F450`` node a like-for-like cross-check of this model.
    """
    arm = 0.1651   # JSBSim F450 Propulsion.xml: rotor hubs at (+-0.1651, +-0.1651) m
    zr = -0.025    # ibid.: hubs 25 mm above the CG (body z is down)
    up = (0.0, 0.0, -1.0)
    radius = 9.4 * 0.0254 / 2   # DJI 9450 propeller, 9.4 in diameter (JSBSim DJI_9450.xml)
    # Solidity: 2 blades x ~20 mm mean chord (measured on a 9450 blade) / disc area.
    sigma = 2 * 0.020 / (math.pi * radius)
    a = 5.7        # thin-airfoil 2 pi corrected for finite blade / low Re (Leishman §3.3)
    # JSBSim DJI_9450.xml static coefficients: C_THRUST(J=0)=0.1288, C_POWER(J=0)=0.0666.
    theta, cd0 = fit_rotor(0.1288, 0.0666, sigma, a)
    return AircraftParams(
        name="quadrotor",
        mass=1.4,                  # JSBSim F450 Mass.xml emptywt 1.4 kg (F450 + 3S pack)
        ixx=0.019, iyy=0.019,      # JSBSim F450 Mass.xml
        izz=0.0252,                # JSBSim F450 Mass.xml
        ixz=0.0,
        # X layout; diagonal pairs spin alike (FR/AL clockwise seen from above,
        # i.e. spin vector down = opposite the up thrust axis, as JSBSim sense=+1).
        rotors=(RotorSpec((arm, arm, zr), up, -1.0), RotorSpec((-arm, -arm, zr), up, -1.0),
                RotorSpec((arm, -arm, zr), up, 1.0), RotorSpec((-arm, arm, zr), up, 1.0)),
        rotor_radius=radius,
        rotor_solidity=sigma,
        rotor_lift_slope=a,
        rotor_pitch=theta,         # fitted: 0.301 rad (reproduces CT = 0.1288 exactly)
        rotor_cd0=cd0,             # fitted: 0.092 (low-Re losses; figure of merit ~0.5)
        # Motor lag: J = 6.05e-5 (prop, DJI_9450.xml) + ~1e-5 (bell) kg m^2, E305
        # Kv = 960 rpm/V, R = 0.117 ohm (JSBSim DJI_E305.xml): 1/tau = (Kt Ke / R
        # + 2 Q/omega) / J ~ 16 1/s at hover.
        tau_motor=0.06,
        # DJI E305 + 9450 on 4S: ~850 g max thrust per rotor -> omega = sqrt(T / kT).
        omega_max=800.0,
        omega_min=100.0,           # ESC idle (motors never stop in flight)
        # JSBSim F450 Metrics.xml / Aero.xml: reference area 0.016129 m^2, CD0 = 1.0.
        aero=AeroCoeffs(s=0.016129, b=0.0, c=0.0, cd_0=1.0),
        autopilot="multirotor",
        # Cascade gains tuned on this model (docs/concepts/aircraft.md): rate loop ~14 rad/s
        # (zeta ~0.6 with the 60 ms motor lag), attitude ~4 rad/s, velocity ~1.5 rad/s.
        gains=dict(k_vel=1.5, ki_vel=0.3, k_alt=1.0, vz_max=3.0, k_vz=3.0, ki_vz=1.0,
                   k_att=4.0, k_rate=12.0, k_yaw=2.0, k_rate_yaw=4.0, tilt_max=0.6,
                   a_max=6.0, v_max=25.0, yaw_rate_max=1.5),
        v_cruise=10.0,
        altitude=100.0,
        spacing=10.0,
    )


def fixedwing_talon() -> AircraftParams:
    """X-UAV TALON-class fixed wing (1.72 m span, 3.3 kg, cruise 20 m/s).

    Geometry and mass from the manufacturer's listing; the non-dimensional
    stability derivatives are the Aerosonde set of Beard & McLain, *Small Unmanned
    Aircraft* (2012), App. E — a conventional small-UAV layout like the TALON's;
    inertias are the Aerosonde's scaled by ``m b^2``.
    """
    b = 1.718          # X-UAV Talon wingspan 1718 mm
    c = 0.21           # mean chord estimated from the planform drawing
    s = b * c          # 0.361 m^2
    ar = b * b / s
    k_mb2 = (3.3 / 13.5) * (b / 2.8956) ** 2   # Aerosonde m = 13.5 kg, b = 2.8956 m
    radius = 11 * 0.0254 / 2   # 11x7 pusher propeller (typical TALON set-up)
    sigma = 2 * 0.022 / (math.pi * radius)   # 2 blades, ~22 mm mean chord
    pitch = 7 * 0.0254
    return AircraftParams(
        name="fixedwing",
        mass=3.3,          # flying weight 3.0-3.8 kg (listing); 4S 5 Ah pack + camera
        ixx=0.8244 * k_mb2, iyy=1.135 * k_mb2, izz=1.759 * k_mb2, ixz=0.1204 * k_mb2,
        rotors=(RotorSpec((-0.35, 0.0, 0.0), (1.0, 0.0, 0.0), 1.0),),
        rotor_radius=radius,
        rotor_solidity=sigma,
        rotor_lift_slope=5.7,
        # Geometric pitch angle at 3/4 radius: atan(pitch / (2 pi 0.75 R)) = 0.264 rad.
        rotor_pitch=math.atan(pitch / (2 * math.pi * 0.75 * radius)),
        rotor_cd0=0.015,   # section profile drag at Re ~ 1e5 (Leishman tab. 7.1 range)
        tau_motor=0.05,    # 1000 Kv-class outrunner with 11 in prop (same derivation as F450)
        omega_max=1300.0,  # 1000 Kv x 14.8 V (4S) loaded to ~84 %: 12 400 rpm
        omega_min=0.0,
        aero=AeroCoeffs(
            s=s, b=b, c=c,
            # Beard & McLain App. E (Aerosonde), per rad:
            cl_0=0.23, cl_a=5.61, cl_q=7.95, cl_de=0.13, cl_max=1.2,
            cd_0=0.043, cd_k=1.0 / (math.pi * 0.9 * ar), cd_de=0.0135,
            cy_b=-0.98, cy_p=0.0, cy_r=0.0, cy_da=0.075, cy_dr=0.19,
            cll_b=-0.13, cll_p=-0.51, cll_r=0.25, cll_da=0.17, cll_dr=0.0024,
            cm_0=0.0135, cm_a=-2.74, cm_q=-38.21, cm_de=-0.99,
            cn_b=0.073, cn_p=-0.069, cn_r=-0.095, cn_da=-0.011, cn_dr=-0.069),
        tau_servo=0.02,    # 9 g micro servo: ~0.1 s / 60 deg, ~20 ms small-signal lag
        delta_max=0.44,    # +-25 deg surface throw
        autopilot="fixedwing",
        # Successive-loop-closure gains tuned on this model (docs/concepts/aircraft.md).
        gains=dict(k_chi=1.2, phi_max=0.6, k_phi=0.8, k_p=0.08, ki_phi=0.1, k_alt=0.03,
                   ki_alt=0.005, theta_max=0.35, k_theta=1.0, k_q=0.15, k_v=0.08,
                   ki_v=0.02, k_r=0.1, v_min=13.0, v_max=30.0, alt_err_max=30.0),
        v_cruise=20.0,     # the paper's v_cru
        altitude=100.0,
        spacing=30.0,
        # 10 ms sub-step: |lambda h| <= 0.52 for the fastest mode (roll subsidence
        # 52 1/s); a 60 s formation flight in turbulence stays within 0.3 m of a
        # 2.5 ms reference, as at 5 ms (docs/concepts/aircraft.md).
        max_substep=0.01,
    )


#: Preset factories by name.
PRESETS = {"quadrotor": quadrotor_f450, "fixedwing": fixedwing_talon}


def preset(name: str) -> AircraftParams:
    """The preset called ``name``; unknown names raise ConfigError naming the field."""
    try:
        return PRESETS[name]()
    except KeyError:
        raise ConfigError("preset",
                          f"unknown preset {name!r}; allowed: {sorted(PRESETS)}") from None
