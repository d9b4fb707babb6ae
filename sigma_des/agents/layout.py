"""Column layouts shared by the numba kernels: the aircraft state and parameter vectors.

The general aircraft keeps its whole swarm state in one ``(n, STATE_DIM)`` float64
array (so a checkpoint is an array copy) and its constants in one flat parameter
vector (so a single compiled kernel serves every preset). The index constants
below are module globals, which numba freezes into the compiled code.
"""

from __future__ import annotations

# --- state columns -----------------------------------------------------------------
# Body-axis velocity relative to the ground (m/s), attitude quaternion (scalar
# first, body -> NED), body rates (rad/s), north/east position and altitude up (m),
# time since start (s), rotor speeds (rad/s), control-surface deflections (rad),
# Dryden turbulence filter states (m/s, along-heading / cross / down axes) and
# autopilot integrators (units depend on the autopilot, see autopilot.py).
(U, V, W, Q0, Q1, Q2, Q3, P, Q, R, XN, YE, H, TIME,
 OM0, OM1, OM2, OM3, DA, DE, DR, TU, TV, TW, I0, I1, I2, I3) = range(28)
STATE_DIM = 28
MAX_ROTORS = 4
STATE_FIELDS: tuple[str, ...] = (
    "u", "v", "w", "q0", "q1", "q2", "q3", "p", "q", "r", "x", "y", "h", "t",
    "omega0", "omega1", "omega2", "omega3", "delta_a", "delta_e", "delta_r",
    "turb_u", "turb_v", "turb_w", "int0", "int1", "int2", "int3",
)

# --- parameter vector ----------------------------------------------------------------
# Rigid body; rotor common block; per-rotor block (position xyz, thrust axis xyz,
# spin sign) x MAX_ROTORS; fixed-wing aerodynamics; actuators; autopilot; mixer;
# trim; environment. Derived entries (KT, KQ, LAMBDA_H, MIX*, trims) are filled by
# aircraft.py, never by the user.
(MASS, IXX, IYY, IZZ, IXZ, NROT,
 ROT_R, ROT_SIGMA, ROT_A, ROT_THETA, ROT_CD0, ROT_LAMBDA_H, KT, KQ,
 TAU_MOTOR, OMEGA_MAX, OMEGA_MIN) = range(17)
ROTOR_BASE = 17           # 7 entries per rotor: px py pz ex ey ez spin
ROTOR_STRIDE = 7
_A = ROTOR_BASE + ROTOR_STRIDE * MAX_ROTORS   # 45
(AERO_S, AERO_B, AERO_C, CL0, CLA, CLQ, CLDE, CLMAX, CD0, CDK, CDDE,
 CYB, CYP, CYR, CYDA, CYDR, CLB, CLP, CLR, CLDA, CLDR,
 CM0, CMA, CMQ, CMDE, CNB, CNP, CNR, CNDA, CNDR,
 TAU_SERVO, DELTA_MAX) = range(_A, _A + 32)
_G = _A + 32              # 77: autopilot gains (meaning per autopilot kind)
AP_KIND = _G              # 0 open loop, 1 multirotor cascade, 2 fixed-wing
GAIN_BASE = _G + 1        # 16 gain slots
N_GAINS = 16
MIX_BASE = GAIN_BASE + N_GAINS   # 4x4 inverse mixer, row-major
(TRIM_OMEGA, TRIM_DE, TRIM_THETA, TRIM_THROTTLE) = range(MIX_BASE + 16, MIX_BASE + 20)
(ENV_WN, ENV_WE, ENV_WD, ENV_TAU, ENV_SHEAR, ENV_HREF, ENV_W20, ENV_TURB_ON,
 ENV_SUBSTEP) = range(MIX_BASE + 20, MIX_BASE + 29)
PARAM_DIM = MIX_BASE + 29
