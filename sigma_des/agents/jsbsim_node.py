"""JSBSim aircraft as DynamicsModel nodes (one FGFDMExec per node), for cross-checks.

``JSBSimModel("F450")`` (a quadrotor, shipped in the ``jsbsim`` package's
aircraft directory) or a fixed wing such as ``c172x`` is driven through the same
interface and the same guidance command ``[v_cmd, chi_cmd, h_cmd, phi_cmd]`` as
the vectorised models. The autopilot is ours, in Python, run at the JSBSim rate
(default 400 Hz): for multirotors (F450) velocity/altitude PI -> attitude ->
body-rate references into the F450's own rate SCAS (``fcs/ScasEngage``); for fixed
wings the same successive-loop closure as autopilot.py on the normalised stick,
pedal and throttle commands.

State row (``STATE_FIELDS``): the published 12 values, time, 4 autopilot
integrators. The real state lives inside each node's FDM, so this model is not
pure: when ``step`` receives a row that is not bit-identical to what that node
returned last (a rollback, a replay, or a fresh swarm), the FDM is re-initialised
from the row (position, body velocities, attitude, rates, integrators). Internal
JSBSim states the row does not hold (rotor rpm, engine and FCS filter states)
restart from their initial-condition values, so rollback by re-init + replay is
approximate (not bit-exact) for JSBSim nodes. Cost: see docs/concepts/aircraft.md (tens of
microseconds per FDM step per aircraft, ~100x the vectorised model).
"""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sigma_des.errors import ConfigError

__all__ = ["JSBSimModel", "available_models", "STATE_FIELDS"]

STATE_FIELDS: tuple[str, ...] = ("u", "v", "w", "phi", "theta", "psi", "p", "q", "r",
                                 "x", "y", "h", "t", "int0", "int1", "int2", "int3")
_FT = 0.3048
_LAT0, _LON0 = 44.7258, -93.0759        # JSBSim F450 initGrnd.xml site
_RE = 6378137.0
_MULTIROTORS = {"F450"}


def _root() -> Path:
    import jsbsim
    return Path(jsbsim.get_default_root_dir())


def available_models() -> list[str]:
    """Aircraft shipped with the installed ``jsbsim`` package."""
    return sorted(p.name for p in (_root() / "aircraft").iterdir()
                  if p.is_dir() and (p / f"{p.name}.xml").exists())


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Silence JSBSim's C++ console output (model-version warnings) at fd level."""
    saved = [os.dup(1), os.dup(2)]
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (*saved, null):
            os.close(fd)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _clip(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else (hi if v > hi else v)


class JSBSimModel:
    """One JSBSim FDM per node behind the DynamicsModel interface (see module doc).

    Args:
        model: JSBSim aircraft name (see :func:`available_models`).
        fdm_rate: JSBSim integration rate (Hz).
        altitude: initial altitude (m).
        spacing: initial grid spacing (m).
        v_cruise: initial / default speed (m/s; 0 for multirotors).
    """

    command_names = ("v_cmd", "chi_cmd", "h_cmd", "phi_cmd")
    command_dim = 4
    state_dim = len(STATE_FIELDS)

    def __init__(self, model: str = "F450", fdm_rate: float = 400.0, altitude: float = 100.0,
                 spacing: float = 10.0, v_cruise: float | None = None) -> None:
        allowed = available_models()
        if model not in allowed:
            raise ConfigError("dynamics", f"unknown JSBSim model {model!r} (jsbsim:<model>); "
                              f"allowed: {allowed}")
        if not fdm_rate > 0:
            raise ConfigError("jsbsim.fdm_rate", f"must be > 0, got {fdm_rate}")
        self.model = model
        self.name = f"jsbsim:{model}"
        self.multirotor = model in _MULTIROTORS
        self.fdm_dt = 1.0 / fdm_rate
        self.altitude = altitude
        self.spacing = spacing
        self.v_cruise = (0.0 if self.multirotor else 50.0) if v_cruise is None else v_cruise
        self._fdm: dict[int, Any] = {}
        self._last: dict[int, NDArray[np.float64]] = {}
        self.hover_throttle = 0.42      # F450: measured level-hover throttle, refined in _new
        self.cruise_throttle = 0.7

    # --- FDM management ------------------------------------------------------------
    def _new(self) -> Any:
        import jsbsim
        with _quiet():
            fdm = jsbsim.FGFDMExec(str(_root()))
            fdm.set_debug_level(0)
            fdm.load_model(self.model)
        fdm.set_dt(self.fdm_dt)
        return fdm

    def _init_from_row(self, fdm: Any, row: NDArray[np.float64]) -> None:
        u, v, w, phi, th, psi, p, q, r, x, y, h = row[:12]
        fdm["ic/terrain-elevation-ft"] = 0.0
        fdm["ic/lat-geod-deg"] = _LAT0 + math.degrees(x / _RE)
        fdm["ic/long-gc-deg"] = _LON0 + math.degrees(y / (_RE * math.cos(math.radians(_LAT0))))
        fdm["ic/h-sl-ft"] = h / _FT
        fdm["ic/u-fps"], fdm["ic/v-fps"], fdm["ic/w-fps"] = u / _FT, v / _FT, w / _FT
        fdm["ic/phi-rad"], fdm["ic/theta-rad"], fdm["ic/psi-true-rad"] = phi, th, psi
        fdm["ic/p-rad_sec"], fdm["ic/q-rad_sec"], fdm["ic/r-rad_sec"] = p, q, r
        with _quiet():
            fdm.run_ic()
        if self.multirotor:
            fdm["fcs/ScasEngage"] = 1.0
        else:
            fdm["propulsion/set-running"] = -1
            fdm["fcs/mixture-cmd-norm"] = 1.0
        self._t = row[12]

    def _row(self, fdm: Any, t: float, ints: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.empty(self.state_dim)
        out[0] = fdm["velocities/u-fps"] * _FT
        out[1] = fdm["velocities/v-fps"] * _FT
        out[2] = fdm["velocities/w-fps"] * _FT
        out[3], out[4], out[5] = (fdm["attitude/phi-rad"], fdm["attitude/theta-rad"],
                                  _wrap(fdm["attitude/psi-rad"]))
        out[6], out[7], out[8] = (fdm["velocities/p-rad_sec"], fdm["velocities/q-rad_sec"],
                                  fdm["velocities/r-rad_sec"])
        out[9] = math.radians(fdm["position/lat-geod-deg"] - _LAT0) * _RE
        out[10] = math.radians(fdm["position/long-gc-deg"] - _LON0) * _RE * math.cos(
            math.radians(_LAT0))
        out[11] = fdm["position/h-sl-meters"]
        out[12] = t
        out[13:17] = ints
        return out

    # --- autopilots (one FDM step) ---------------------------------------------------
    def _ap_multirotor(self, fdm: Any, cmd: NDArray[np.float64], ints: NDArray[np.float64],
                       h: float) -> None:
        vc, chi, hc, phic = cmd
        vn, ve = fdm["velocities/v-north-fps"] * _FT, fdm["velocities/v-east-fps"] * _FT
        vup = -fdm["velocities/v-down-fps"] * _FT
        phi, th, psi = fdm["attitude/phi-rad"], fdm["attitude/theta-rad"], fdm["attitude/psi-rad"]
        en, ee = vc * math.cos(chi) - vn, vc * math.sin(chi) - ve
        ints[0] = _clip(ints[0] + h * en, -10, 10)
        ints[1] = _clip(ints[1] + h * ee, -10, 10)
        an, ae = 1.0 * en + 0.1 * ints[0], 1.0 * ee + 0.1 * ints[1]
        afwd = math.cos(psi) * an + math.sin(psi) * ae
        argt = -math.sin(psi) * an + math.cos(psi) * ae
        thc = _clip(-afwd / 9.81, -0.35, 0.35)
        phc = _clip(phic if phic == phic else argt / 9.81, -0.35, 0.35)
        ez = _clip(1.0 * (hc - fdm["position/h-sl-meters"]), -2.0, 2.0) - vup
        ints[2] = _clip(ints[2] + h * ez, -2.0, 2.0)
        thr = _clip(self.hover_throttle + 0.15 * ez + 0.1 * ints[2], 0.0, 1.0)
        fdm["fcs/aileron-cmd-norm"] = _clip(3.0 * (phc - phi) / 0.75, -1, 1)
        fdm["fcs/elevator-cmd-norm"] = _clip(3.0 * (thc - th) / 0.75, -1, 1)
        fdm["fcs/rudder-cmd-norm"] = _clip(1.0 * _wrap(chi - psi) / 0.75, -1, 1)
        fdm["fcs/throttle-cmd-norm"] = thr

    def _ap_fixedwing(self, fdm: Any, cmd: NDArray[np.float64], ints: NDArray[np.float64],
                      h: float) -> None:
        vc, chi_c, hc, phic = cmd
        vn, ve = fdm["velocities/v-north-fps"] * _FT, fdm["velocities/v-east-fps"] * _FT
        phi, th = fdm["attitude/phi-rad"], fdm["attitude/theta-rad"]
        va = fdm["velocities/vt-fps"] * _FT
        phc = phic if phic == phic else _clip(1.0 * _wrap(chi_c - math.atan2(ve, vn)), -0.5, 0.5)
        fdm["fcs/aileron-cmd-norm"] = _clip(2.0 * (phc - phi) - 0.3 * fdm["velocities/p-rad_sec"],
                                            -1, 1)
        eh = _clip(hc - fdm["position/h-sl-meters"], -30, 30)
        ints[1] = _clip(ints[1] + h * eh, -20, 20)
        thc = _clip(0.02 * eh + 0.002 * ints[1] + 0.02, -0.25, 0.25)
        # JSBSim: negative elevator command = nose up.
        fdm["fcs/elevator-cmd-norm"] = _clip(-3.0 * (thc - th) + 0.5 * fdm["velocities/q-rad_sec"],
                                             -1, 1)
        ev = vc - va
        ints[2] = _clip(ints[2] + h * ev, -20, 20)
        fdm["fcs/throttle-cmd-norm"] = _clip(self.cruise_throttle + 0.05 * ev + 0.01 * ints[2],
                                             0, 1)

    # --- DynamicsModel -------------------------------------------------------------------
    def initial_state(self, n: int) -> NDArray[np.float64]:
        """Level flight (or hover) on a grid at ``altitude``, heading north."""
        side = max(1, math.ceil(math.sqrt(n)))
        s = np.zeros((n, self.state_dim))
        i = np.arange(n)
        s[:, 0] = self.v_cruise
        s[:, 9] = (i // side) * self.spacing
        s[:, 10] = (i % side) * self.spacing
        s[:, 11] = self.altitude
        return s

    def default_command(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """Hold heading and altitude at the default speed."""
        cmd = np.empty((state.shape[0], 4))
        cmd[:, 0] = self.v_cruise
        cmd[:, 1] = state[:, 5]
        cmd[:, 2] = state[:, 11]
        cmd[:, 3] = np.nan
        return cmd

    def step(self, state: NDArray[np.float64], command: NDArray[np.float64], dt: float,
             frame: int, nodes: NDArray[np.int64]) -> NDArray[np.float64]:
        """Advance every node's FDM by ``dt`` (re-initialising it if ``state`` is not its own)."""
        out = np.empty_like(state, dtype=np.float64)
        nsub = max(1, int(round(dt / self.fdm_dt)))
        h = dt / nsub
        ap = self._ap_multirotor if self.multirotor else self._ap_fixedwing
        for i, node in enumerate(np.asarray(nodes, dtype=np.int64).tolist()):
            row = np.asarray(state[i], dtype=np.float64)
            fdm = self._fdm.get(node)
            if fdm is None:
                fdm = self._fdm[node] = self._new()
            last = self._last.get(node)
            if last is None or not np.array_equal(last, row):
                self._init_from_row(fdm, row)
            cmd = np.array(command[i], dtype=np.float64)
            for k, default in enumerate((self.v_cruise, row[5], row[11])):
                if cmd[k] != cmd[k]:
                    cmd[k] = default
            ints = row[13:17].copy()
            fdm.set_dt(h)
            for _ in range(nsub):
                ap(fdm, cmd, ints, h)
                fdm.run()
            out[i] = self._row(fdm, row[12] + dt, ints)
            self._last[node] = out[i].copy()
        return out

    def observe(self, state: NDArray[np.float64]) -> NDArray[np.float64]:
        """The published ``(n, 12)`` state."""
        return np.array(state[:, :12], dtype=np.float64)
