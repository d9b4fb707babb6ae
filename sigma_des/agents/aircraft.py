"""The general aircraft: a vectorised 6-DoF DynamicsModel with its autopilot inside.

Guidance command (common to every model in the registry, behaviours rely on it):

====  ===========  ======================================================
col   name         meaning
====  ===========  ======================================================
0     ``v_cmd``    horizontal speed (m/s); airspeed for fixed wings
1     ``chi_cmd``  course / heading, rad, NED (0 = north, +pi/2 = east)
2     ``h_cmd``    altitude (m, up)
3     ``phi_cmd``  roll-angle override (rad) or NaN = not used
====  ===========  ======================================================

NaN in columns 0–2 keeps the current value (resolved at the start of each step);
an all-NaN row is "no new command" for the engine. The state layout is
layout.STATE_FIELDS (28 columns: body velocity, quaternion, rates, position,
time, rotor speeds, surfaces, turbulence filters, autopilot integrators), so a
checkpoint is ``state.copy()`` and rollback is re-running :meth:`step`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from sigma_des.agents import layout as L
from sigma_des.agents.atmosphere import gravity_scalar, isa_scalar
from sigma_des.agents.forces import forces_moments
from sigma_des.agents.kernel import step_kernel
from sigma_des.agents.params import AircraftParams
from sigma_des.agents.presets import preset
from sigma_des.agents.wind import WindConfig
from sigma_des.core.rng import RandomStreams
from sigma_des.errors import ConfigError

__all__ = ["GeneralAircraft", "COMMAND_NAMES", "ACTUATOR_NAMES", "observe_state"]

COMMAND_NAMES: tuple[str, ...] = ("v_cmd", "chi_cmd", "h_cmd", "phi_cmd")
ACTUATOR_NAMES: tuple[str, ...] = ("omega0", "omega1", "omega2", "omega3",
                                   "delta_a", "delta_e", "delta_r")
_NO_ACT = np.zeros((0, 7))


@njit(cache=True)
def forces_of(x: np.ndarray, prm: np.ndarray, rho: float) -> tuple[float, float, float,
                                                                   float, float, float]:
    """Non-inlined wrapper of forces_moments in still air (for trim)."""
    return forces_moments(x, prm, 0.0, 0.0, 0.0, rho)


@njit(cache=True)
def _step_frames(s0: np.ndarray, cmd: np.ndarray, dts: np.ndarray, first: np.int64,
                 nodes: np.ndarray, prm: np.ndarray, key: np.uint64, out: np.ndarray) -> None:
    cur = s0.copy()
    nxt = np.empty_like(cur)
    for j in range(dts.shape[0]):
        step_kernel(cur, cmd, _NO_ACT, dts[j], first + j, nodes, prm, key, nxt)
        out[j] = nxt[0]
        cur[0] = nxt[0]


@njit(cache=True)
def _observe_rows(state: np.ndarray, obs: np.ndarray, args: np.ndarray) -> None:
    """``observe_state`` without its three inverse trigonometric calls: the copied
    columns of ``obs`` and the arguments of ``phi = arctan2(args[0], args[1])``,
    ``theta = arcsin(args[2])`` (clipped to [-1, 1]) and ``psi = arctan2(args[3],
    args[4])`` (the same operations as the numpy expressions they replace)."""
    for r in range(state.shape[0]):
        q0, q1, q2, q3 = state[r, L.Q0], state[r, L.Q1], state[r, L.Q2], state[r, L.Q3]
        args[0, r] = 2.0 * (q0 * q1 + q2 * q3)
        args[1, r] = 1.0 - 2.0 * (q1 * q1 + q2 * q2)
        s = 2.0 * (q0 * q2 - q3 * q1)
        if s < -1.0:  # np.clip (NaN stays NaN)
            s = -1.0
        elif s > 1.0:
            s = 1.0
        args[2, r] = s
        args[3, r] = 2.0 * (q0 * q3 + q1 * q2)
        args[4, r] = 1.0 - 2.0 * (q2 * q2 + q3 * q3)
        for c in range(3):
            obs[r, c] = state[r, L.U + c]
            obs[r, 6 + c] = state[r, L.P + c]
            obs[r, 9 + c] = state[r, L.XN + c]


def observe_state(state: NDArray[np.float64], out: NDArray[np.float64] | None = None
                  ) -> NDArray[np.float64]:
    """Published ``(n, 12)`` state ``[u v w phi theta psi p q r x y h]`` of aircraft rows.

    The Euler angles from the attitude quaternion: their arguments compiled
    (:func:`_observe_rows`), the inverse trigonometric functions numpy's (whose float64
    ``arctan2`` is SIMD code on AVX-512 machines, not the C library's that compiled code
    would call: different in the last bit of some values). Each is evaluated over
    contiguous rows (in place in its first argument's row) whatever ``out`` is, so the
    bits do not depend on where the result goes.

    Args:
        state: ``(n, STATE_DIM)`` aircraft rows.
        out: a C-contiguous ``(n, 12)`` float64 array to write into (e.g. a ring slot,
            no temporary of that size), or None for a new array.

    Returns:
        ``out``, or the new array.
    """
    state = np.ascontiguousarray(state, dtype=np.float64)
    n = state.shape[0]
    if out is None:
        out = np.empty((n, 12))
    elif out.shape != (n, 12) or out.dtype != np.float64 or not out.flags.c_contiguous:
        raise ValueError(f"observe: out must be a C-contiguous float64 ({n}, 12) array")
    args = np.empty((5, n))
    _observe_rows(state, out, args)
    out[:, 3] = np.arctan2(args[0], args[1], out=args[0])
    out[:, 4] = np.arcsin(args[2], out=args[2])
    out[:, 5] = np.arctan2(args[3], args[4], out=args[3])
    return out


class GeneralAircraft:
    """Rotors + fixed-wing aerodynamics + gravity on one 6-DoF integrator (see module doc).

    Args:
        params: an :class:`AircraftParams` or a preset name (``quadrotor``, ``fixedwing``).
        wind: wind field (default: still air).
        seed: root seed of the turbulence stream.
        **overrides: fields of the params to replace (e.g. ``mass=1.6``).
    """

    command_names = COMMAND_NAMES
    command_dim = 4
    state_dim = L.STATE_DIM

    def __init__(self, params: AircraftParams | str = "quadrotor", wind: WindConfig | None = None,
                 seed: int = 0, **overrides: float) -> None:
        p = preset(params) if isinstance(params, str) else params
        if overrides:
            known = {f.name for f in dataclasses.fields(AircraftParams)}
            bad = sorted(set(overrides) - known)
            if bad:
                raise ConfigError(f"{p.name}.{bad[0]}",
                                  f"unknown parameter; allowed: {sorted(known)}")
            p = dataclasses.replace(p, **overrides)  # type: ignore[arg-type]
        self.params = p
        self.name = p.name
        self.wind = wind or WindConfig()
        self.seed = int(seed)
        self.key = RandomStreams(self.seed).stream("agents.turbulence").key
        prm = p.to_array()
        self.wind.write(prm)
        self._mixer(prm)
        self.prm = prm
        self.trim = self._trim(prm)

    # --- set-up --------------------------------------------------------------------------
    def _mixer(self, prm: NDArray[np.float64]) -> None:
        """Inverse of (rotor thrusts) -> (total thrust up, L, M, N) for 4 rotors."""
        if len(self.params.rotors) != 4:
            return
        ratio = prm[L.KQ] / prm[L.KT]
        a = np.zeros((4, 4))
        for i in range(len(self.params.rotors)):
            k = L.ROTOR_BASE + L.ROTOR_STRIDE * i
            pos, ax, spin = prm[k:k + 3], prm[k + 3:k + 6], prm[k + 6]
            a[0, i] = -ax[2]
            a[1:, i] = np.cross(pos, ax) - spin * ratio * ax
        try:
            inv = np.linalg.inv(a)
        except np.linalg.LinAlgError:
            raise ConfigError(f"{self.name}.rotors", "rotor layout cannot control roll, "
                              "pitch and yaw independently (singular mixer)") from None
        prm[L.MIX_BASE:L.MIX_BASE + 16] = inv.ravel()

    def hover_omega(self, h: float | None = None) -> float:
        """Rotor speed (rad/s) at which all rotors together carry the weight at ``h``."""
        h = self.params.altitude if h is None else h
        _, _, rho = isa_scalar(h)
        lam_h, ct = self.params.hover_inflow
        r = self.params.rotor_radius
        up = -sum(rot.axis[2] / np.linalg.norm(rot.axis) for rot in self.params.rotors)
        kt = ct * rho * math.pi * r ** 4
        return math.sqrt(self.params.mass * gravity_scalar(h) / (up * kt))

    def _trim(self, prm: NDArray[np.float64]) -> dict[str, float]:
        """Hover (multirotor) or level-flight (fixed-wing) trim at the preset altitude."""
        p = self.params
        if p.autopilot != "fixedwing":
            w = self.hover_omega() if p.autopilot == "multirotor" else 0.0
            prm[L.TRIM_OMEGA] = w
            return {"omega": w, "alpha": 0.0, "delta_e": 0.0, "throttle": w / p.omega_max}
        _, _, rho = isa_scalar(p.altitude)
        g = gravity_scalar(p.altitude)
        v = p.v_cruise

        def residual(z: NDArray[np.float64]) -> list[float]:
            alpha, de, om = z
            x = self._level_row(alpha, de, om, v)
            fx, _, fz, _, mm, _ = forces_of(x, prm, rho)
            return [fx / p.mass - g * math.sin(alpha), fz / p.mass + g * math.cos(alpha),
                    mm / p.iyy]

        from scipy.optimize import fsolve  # here: its import holds ~36 MB

        # The first start suits a small-wing UAV; a large wing trims nose-down at low
        # power, where Newton's steps from the first start leave the thrust's range.
        for a0, om0 in ((0.05, 0.9), (-0.1, 0.7), (0.0, 0.5)):
            sol, _, ok, msg = fsolve(residual, [a0, 0.0, om0 * p.omega_max], full_output=True)
            alpha, de, om = (float(s) for s in sol)
            if ok == 1 and 0 < om < p.omega_max and abs(de) <= p.delta_max:
                break
        else:
            raise ConfigError(f"{p.name}.v_cruise", f"no level-flight trim at {v} m/s ({msg})")
        prm[L.TRIM_OMEGA], prm[L.TRIM_DE], prm[L.TRIM_THETA] = om, de, alpha
        prm[L.TRIM_THROTTLE] = om / p.omega_max
        return {"omega": om, "alpha": alpha, "delta_e": de, "throttle": om / p.omega_max}

    @staticmethod
    def _level_row(alpha: float, de: float, om: float, v: float) -> NDArray[np.float64]:
        x = np.zeros(L.STATE_DIM)
        x[L.U], x[L.W] = v * math.cos(alpha), v * math.sin(alpha)
        x[L.Q0], x[L.Q2] = math.cos(alpha / 2), math.sin(alpha / 2)
        x[L.OM0], x[L.DE] = om, de
        return x

    # --- DynamicsModel -------------------------------------------------------------------
    def initial_state(self, n: int) -> NDArray[np.float64]:
        """Trimmed swarm on a square grid at the preset altitude, heading north."""
        p = self.params
        side = max(1, math.ceil(math.sqrt(n)))
        i = np.arange(n)
        if p.autopilot == "fixedwing":
            row = self._level_row(self.trim["alpha"], self.trim["delta_e"], self.trim["omega"],
                                  p.v_cruise)
        else:
            row = np.zeros(L.STATE_DIM)
            row[L.Q0] = 1.0
            row[L.OM0:L.OM0 + len(p.rotors)] = self.trim["omega"]
        s = np.tile(row, (n, 1))
        s[:, L.XN] = (i // side) * p.spacing
        s[:, L.YE] = (i % side) * p.spacing
        s[:, L.H] = p.altitude
        return s

    def default_command(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """Hold heading and altitude at the cruise speed (multirotors: hover in place)."""
        obs = observe_state(state)
        cmd = np.empty((state.shape[0], 4))
        cmd[:, 0] = self.params.v_cruise if self.params.autopilot == "fixedwing" else 0.0
        cmd[:, 1] = obs[:, 5]
        cmd[:, 2] = obs[:, 11]
        cmd[:, 3] = np.nan
        return cmd

    def step(self, state: NDArray[np.float64], command: NDArray[np.float64], dt: float,
             frame: int, nodes: NDArray[np.int64]) -> NDArray[np.float64]:
        """Advance every aircraft by ``dt`` under its autopilot (returns a new array)."""
        state, command, nodes = self._check(state, command, nodes, 4)
        out = np.empty_like(state)
        step_kernel(state, command, _NO_ACT, float(dt), np.int64(frame), nodes, self.prm,
                    self.key, out)
        return out

    def step_into(self, state: NDArray[np.float64], command: NDArray[np.float64], dt: float,
                  frame: int, nodes: NDArray[np.int64], out: NDArray[np.float64]) -> None:
        """:meth:`step` written into ``out`` (a C-contiguous float64 array of the state's
        shape, not overlapping it: e.g. a checkpoint ring's slot): the same bits, no
        new array."""
        state, command, nodes = self._check(state, command, nodes, 4)
        if out.shape != state.shape or out.dtype != np.float64 or not out.flags.c_contiguous:
            raise ValueError(f"{self.name}: out must be a C-contiguous float64 "
                             f"{state.shape} array")
        if np.may_share_memory(out, state):
            raise ValueError(f"{self.name}: out must not overlap the state")
        step_kernel(state, command, _NO_ACT, float(dt), np.int64(frame), nodes, self.prm,
                    self.key, out)

    def step_frames(self, state: NDArray[np.float64], command: NDArray[np.float64],
                    dts: NDArray[np.float64], first_frame: int, node: int
                    ) -> NDArray[np.float64]:
        """One aircraft through consecutive frames (a time-warp re-simulation).

        Row ``j`` of the result equals ``step`` of row ``j-1`` (``state`` for j = 0)
        by ``dts[j]`` to frame ``first_frame + j``: the same compiled row step, without
        a Python call per frame.

        Args:
            state: ``(STATE_DIM,)`` start state.
            command: ``(4,)`` command held over all frames.
            dts: ``(m,)`` frame steps.
            first_frame: frame the first step leads to.
            node: the aircraft's node id.
        """
        s0 = np.ascontiguousarray(state, dtype=np.float64).reshape(1, L.STATE_DIM)
        cmd = np.ascontiguousarray(command, dtype=np.float64).reshape(1, 4)
        out = np.empty((len(dts), L.STATE_DIM))
        _step_frames(s0, cmd, np.ascontiguousarray(dts, dtype=np.float64),
                     np.int64(first_frame), np.array([node], dtype=np.int64), self.prm,
                     self.key, out)
        return out

    def step_open_loop(self, state: NDArray[np.float64], actuators: NDArray[np.float64],
                       dt: float, frame: int, nodes: NDArray[np.int64]) -> NDArray[np.float64]:
        """Advance with the autopilot bypassed: ``actuators`` columns ACTUATOR_NAMES."""
        state, actuators, nodes = self._check(state, actuators, nodes, 7)
        prm = self.prm.copy()
        prm[L.AP_KIND] = 0.0
        out = np.empty_like(state)
        step_kernel(state, np.zeros((0, 4)), actuators, float(dt), np.int64(frame), nodes, prm,
                    self.key, out)
        return out

    def observe(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """The published ``(n, 12)`` state (OBS_FIELDS)."""
        return observe_state(state)

    def observe_into(self, state: NDArray[np.float64], out: NDArray[np.float64]) -> None:
        """:meth:`observe` written into ``out`` (C-contiguous ``(n, 12)`` float64)."""
        observe_state(state, out)

    def _check(self, state: NDArray[np.float64], cmd: NDArray[np.float64],
               nodes: NDArray[np.int64], width: int
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        state = np.ascontiguousarray(state, dtype=np.float64)
        cmd = np.ascontiguousarray(cmd, dtype=np.float64)
        nodes = np.ascontiguousarray(nodes, dtype=np.int64)
        n = state.shape[0]
        if state.ndim != 2 or state.shape[1] != L.STATE_DIM:
            raise ValueError(f"{self.name}: state must be (n, {L.STATE_DIM}), got {state.shape}")
        if cmd.shape != (n, width):
            raise ValueError(f"{self.name}: command must be ({n}, {width}), got {cmd.shape}")
        if nodes.shape != (n,):
            raise ValueError(f"{self.name}: nodes must be ({n},), got {nodes.shape}")
        return state, cmd, nodes
