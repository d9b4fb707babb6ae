"""The fixed-wing fit against JSBSim's ``minisgs`` glider (the paper's Fig. 15 in kind).

Starting point ("before"): the fixed-wing preset's aerodynamic derivatives (the
Aerosonde set of Beard & McLain, App. E) on the glider's measured structure —
mass, inertia, wing area, span, chord and surface limit read from JSBSim
(:func:`~sigma_des.tuning.glider_log.glider_structure`), no propeller thrust
(the log's ``omega0`` is 0), surfaces without lag (minisgs has no actuator model:
``tau_servo`` 1 ms) and ``cd_0`` from the logged steady glide (:func:`glide_cd0`).
The GA tunes :data:`GENES` within the documented bounds; inertia is held (only
moment coefficient / inertia is identifiable: :func:`inertia_ridge` shows it).

Reference only, never fitted to: JSBSim's own coefficients mapped onto our linear
structure (:func:`jsbsim_coefficients`), to say which fitted genes match the
model they came from and which absorb a structural difference.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from sigma_des.agents.params import AircraftParams
from sigma_des.agents.presets import preset
from sigma_des.tuning.flightlog import FlightLog, resample
from sigma_des.tuning.ga import Evaluator
from sigma_des.tuning.replay import windows
from sigma_des.tuning.spec import TuneSpec, get_value, with_values

__all__ = ["GENES", "LATERAL", "LONGITUDINAL", "STAGES", "STRUCTURE", "PROP_11X10", "powered",
           "glider_start",
           "glide_cd0", "jsbsim_coefficients", "sensitivity", "inertia_ridge", "MOMENT_COEFFS"]

#: Genes and their bounds. Ranges span the small-UAV and sailplane values of the
#: literature (Beard & McLain App. E: Aerosonde and Zagi; Roskam, *Airplane Flight
#: Dynamics* I, ch. 4 trends; JSBSim's own small-aircraft sets): lift from pitch rate
#: 0–10 and from elevator 0–0.5 per rad, lift slope 2–6.5
#: per rad (low-aspect to high-aspect wings), static margin from neutral to very
#: stable (cm_a 0 to -3), pitch damping -2 to -50, elevator power -0.3 to -2.5,
#: roll damping -0.2 to -0.8, aileron power 0.05 to 0.4, dihedral effect 0 to
#: -0.2, weathercock 0 to 0.15, yaw damping -0.005 to -0.2, adverse yaw 0.05 to
#: -0.25, rudder power -0.01 to -0.12, side force -0.1 to -1.2.
GENES: dict[str, tuple[float, float]] = {
    "cl_q": (0.0, 10.0), "cl_de": (0.0, 0.5), "cl_0": (0.0, 0.8), "cl_a": (2.0, 6.5),
    "cm_0": (-0.05, 0.05), "cm_a": (-3.0, 0.0), "cm_q": (-50.0, -2.0), "cm_de": (-2.5, -0.3),
    "cll_p": (-0.8, -0.2), "cll_da": (0.05, 0.4), "cll_b": (-0.2, 0.0), "cll_r": (0.0, 0.3),
    "cn_b": (0.0, 0.15), "cn_r": (-0.2, -0.005), "cn_p": (-0.25, 0.05),
    "cn_dr": (-0.12, -0.01), "cy_b": (-1.2, -0.1),
}
#: The longitudinal genes (tuned on pitch) and the lateral-directional ones (on roll, yaw).
LONGITUDINAL = ("cl_q", "cl_de", "cl_0", "cl_a", "cm_0", "cm_a", "cm_q", "cm_de")
LATERAL = ("cll_p", "cll_da", "cll_b", "cll_r", "cn_b", "cn_r", "cn_p", "cn_dr", "cy_b")
#: Tuning stages (name, genes, DTW channels): decoupled axes, as in flight-test system
#: identification; each stage is one ``sigma-des tune`` run started from the previous fit.
STAGES: tuple[tuple[str, tuple[str, ...], tuple[str, ...]], ...] = (
    ("lateral", LATERAL, ("phi", "p", "r")), ("longitudinal", LONGITUDINAL, ("theta", "q")))
#: Structural parameters taken from JSBSim (the "measured" ones), not tuned.
STRUCTURE = ("mass", "ixx", "iyy", "izz", "ixz", "s", "b", "c", "delta_max")
#: Moment coefficients: scaled with the inertia they leave the motion unchanged.
MOMENT_COEFFS = ("cll_b", "cll_p", "cll_r", "cll_da", "cll_dr", "cm_0", "cm_a", "cm_q",
                 "cm_de", "cn_b", "cn_p", "cn_r", "cn_da", "cn_dr")


def glider_start(structure: dict[str, float]) -> AircraftParams:
    """The preset's derivatives on the glider's measured structure (cd_0 set later)."""
    vals = {k: structure[k] for k in STRUCTURE}
    vals["tau_servo"] = 0.001
    return with_values(preset("fixedwing"), vals)


def glide_cd0(log: FlightLog, params: AircraftParams, seconds: float = 1.0) -> float:
    """``cd_0`` from the log's first ``seconds`` of steady glide (a measured glide ratio).

    In a steady glide ``D = W sin(-gamma)`` and ``L = W cos(gamma)``; ``cd_0 = CD -
    cd_k CL^2`` with the preset's induced-drag factor. The density is ISA at the
    logged altitude, gravity the model's at that altitude.
    """
    from sigma_des.agents.atmosphere import gravity_scalar, isa_scalar

    k = max(2, int(round(seconds / float(log.t[1] - log.t[0]))))
    o = log.obs[:k]
    v = float(np.sqrt((o[:, 0:3] ** 2).sum(axis=1)).mean())
    sink = -float(np.polyfit(log.t[:k], o[:, 11], 1)[0])
    gamma = -math.asin(min(1.0, max(-1.0, sink / v)))
    h = float(o[:, 11].mean())
    rho = float(isa_scalar(h)[2])
    qs = 0.5 * rho * v * v * params.aero.s
    w = params.mass * gravity_scalar(h)
    cl, cd = w * math.cos(gamma) / qs, -w * math.sin(gamma) / qs
    return max(1e-4, cd - params.aero.cd_k * cl * cl)


#: 11x10 propeller (pitch angle at 3/4 radius): the preset's 11x7 runs out of thrust
#: at the preset's 20 m/s cruise on the glider's large wing; the coarser pitch trims it.
PROP_11X10 = math.atan(10 * 0.0254 / (2 * math.pi * 0.75 * 11 * 0.0254 / 2))


#: Autopilot gains retuned for the glider's airframe (the preset's weave on it: a 90 deg
#: course step overshoots 0.4 rad and has not settled after 28 s): a slower course loop,
#: more roll-rate damping and a stronger yaw damper (:func:`course_step`).
GAINS = {"k_chi": 0.6, "k_p": 0.2, "k_r": 0.5}


def powered(fitted: Path, out: Path) -> Path:
    """The fitted glider with the preset's motor, an 11x10 propeller and :data:`GAINS`
    (for ``compare`` and the formation study, which fly at the preset's cruise speed)."""
    from sigma_des.agents.fitted import GAIN_PREFIX, read_fitted, write_fitted

    kind, values = read_fitted(fitted)
    values["rotor_pitch"] = PROP_11X10
    values.update({GAIN_PREFIX + k: v for k, v in GAINS.items()})
    return write_fitted(out, kind, values, {
        "what": "fixed wing fitted to JSBSim's minisgs glider (sigma-des tune, decoupled "
                "stages) with the preset's motor, an 11x10 propeller and retuned course, "
                "roll-rate and yaw-damper gains",
        "source": "experiments/fixed_wing_fit.py"})


def course_step(params: AircraftParams, seconds: float = 30.0, dt: float = 0.01
                ) -> dict[str, float]:
    """A 90 deg course step at cruise under the autopilot: overshoot (rad), the last time
    the course error exceeds 0.05 rad (s), the largest sideslip and bank (rad)."""
    from sigma_des.agents.aircraft import GeneralAircraft

    m = GeneralAircraft(params)
    s = m.initial_state(1)
    cmd = m.default_command(s)
    cmd[:, 1] = math.pi / 2
    rows = []
    for k in range(int(round(seconds / dt))):
        s = m.step(s, cmd, dt, k + 1, np.zeros(1, dtype=np.int64))
        rows.append(m.observe(s)[0])
    o = np.array(rows)
    v = np.sqrt((o[:, 0:3] ** 2).sum(axis=1))
    err = math.pi / 2 - np.unwrap(o[:, 5] + np.arctan2(o[:, 1], o[:, 0]))
    late = np.flatnonzero(np.abs(err) > 0.05)
    return {"overshoot": float(max(0.0, -err.min())),
            "settle_s": float((late[-1] + 1) * dt) if late.size else 0.0,
            "beta_max": float(np.abs(np.arcsin(o[:, 1] / v)).max()),
            "phi_max": float(np.abs(o[:, 3]).max())}


def trim_moments(params: AircraftParams, speeds: tuple[float, ...] = (9.0, 10.0, 11.0, 12.0)
                 ) -> list[dict[str, float]]:
    """Our pitch moment at JSBSim's trimmed glide, per speed: ``cm_0 + cm_a alpha + cm_de
    de`` and the pitch acceleration it gives (rad/s^2); JSBSim's is 0 (it is trimmed)."""
    from sigma_des.agents.atmosphere import isa_scalar
    from sigma_des.tuning.glider_log import GlideSpec, fly_glider

    out = []
    a = params.aero
    for v in speeds:
        log = fly_glider(GlideSpec(speed=v, duration=2.0, warmup=12.0, noise=False))
        o = log.obs[:50]
        alpha = float(np.arctan2(o[:, 2], o[:, 0]).mean())
        de = float(log.act[:50, 2].mean())
        cm = a.cm_0 + a.cm_a * alpha + a.cm_de * de
        qbar = 0.5 * float(isa_scalar(float(o[:, 11].mean()))[2]) * v * v
        out.append({"speed": v, "alpha": alpha, "delta_e": de, "cm": cm,
                    "q_dot": qbar * a.s * a.c * cm / params.iyy})
    return out


def _coefficients(xml: Path) -> dict[str, float]:
    """Every constant ``aero/coefficient/<name>`` of a JSBSim aircraft file."""
    out: dict[str, float] = {}
    for fn in ET.parse(xml).getroot().iter("function"):
        name = fn.get("name", "")
        val = fn.find("./product/value")
        if name.startswith("aero/coefficient/") and val is not None and val.text:
            out[name.rsplit("/", 1)[1]] = float(val.text)
    return out


def _cl_table(xml: Path) -> np.ndarray:
    """The ``CLwbh`` lift table (alpha rad, CL)."""
    for fn in ET.parse(xml).getroot().iter("function"):
        if fn.get("name", "").endswith("/CLwbh"):
            text = fn.find(".//tableData")
            assert text is not None and text.text
            return np.array([float(x) for x in text.text.split()]).reshape(-1, 2)
    raise KeyError("CLwbh")


def jsbsim_coefficients(aircraft: str, alpha: tuple[float, float]) -> dict[str, float]:
    """JSBSim's coefficients of ``aircraft`` in our names (a reference, never fitted to).

    ``cm_q`` is JSBSim's ``Cmq + Cmadot`` (our model has no alpha-dot term; in pitch
    motion at constant flight path alpha-dot equals q); ``cl_0`` and ``cl_a`` are the
    least-squares line through JSBSim's lift table over ``alpha`` (rad), the range flown.
    """
    import jsbsim

    xml = Path(jsbsim.get_default_root_dir()) / "aircraft" / aircraft / f"{aircraft}.xml"
    c = _coefficients(xml)
    tab = _cl_table(xml)
    m = (tab[:, 0] >= alpha[0] - 0.02) & (tab[:, 0] <= alpha[1] + 0.02)
    slope, icpt = np.polyfit(tab[m, 0], tab[m, 1], 1)
    names = {"CYb": "cy_b", "CYda": "cy_da", "CYdr": "cy_dr", "CLDe": "cl_de", "Clb": "cll_b",
             "Clp": "cll_p", "Clr": "cll_r", "Clda": "cll_da", "Cldr": "cll_dr",
             "Cmalpha": "cm_a", "Cmo": "cm_0", "Cmde": "cm_de", "Cnb": "cn_b", "Cnp": "cn_p",
             "Cnr": "cn_r", "Cnda": "cn_da", "Cndr": "cn_dr"}
    out = {ours: c[theirs] for theirs, ours in names.items() if theirs in c}
    out["cm_q"] = c.get("Cmq", 0.0) + c.get("Cmadot", 0.0)
    for ours, theirs in (("cl_q", "CLq"), ("cy_p", "CYp"), ("cy_r", "CYr")):
        out[ours] = c.get(theirs, 0.0)          # a term the file lacks is 0, not our prior
    out["cl_0"], out["cl_a"] = float(icpt), float(slope)
    return out


def _evaluator(log: FlightLog, params: AircraftParams, names: tuple[str, ...],
               spec: TuneSpec) -> Evaluator:
    win = windows(resample(log, spec.rate), spec.segment)
    return Evaluator(win, params, names, spec.channels_of(log.kind), None, spec.band)


def sensitivity(log: FlightLog, params: AircraftParams, names: tuple[str, ...],
                spec: TuneSpec, step: float = 0.1) -> list[dict[str, Any]]:
    """Fitness at each gene's value times ``1 -+ step`` (the others held): a local profile.

    Returns per gene the fitness at the fitted values (``r0``) and the relative
    increase at both ends, ``(r - r0) / r0``; one batched replay for all of them.
    """
    ev = _evaluator(log, params, names, spec)
    x0 = np.array([get_value(params, g) for g in names])
    xs = [x0]
    for i in range(len(names)):
        for f in (1.0 - step, 1.0 + step):
            x = x0.copy()
            x[i] *= f
            xs.append(x)
    r = ev(np.array(xs))
    r0 = float(r[0])
    return [{"name": g, "value": float(x0[i]), "r0": r0,
             "rise_low": float(r[1 + 2 * i] / r0 - 1.0),
             "rise_high": float(r[2 + 2 * i] / r0 - 1.0)} for i, g in enumerate(names)]


#: Gene groups whose joint scaling is profiled: roll damping with aileron power (a roll
#: mode faster than the log interval shows only their ratio) and the static pitch balance.
GROUPS: dict[str, tuple[str, ...]] = {"roll": ("cll_p", "cll_da"),
                                      "pitch_static": ("cm_0", "cm_a", "cm_de")}


def joint_profile(log: FlightLog, params: AircraftParams, spec: TuneSpec,
                  factors: tuple[float, ...] = (0.8, 1.25)) -> dict[str, list[dict[str, float]]]:
    """Fitness with each :data:`GROUPS` group scaled by ``k`` together, relative to none."""
    out: dict[str, list[dict[str, float]]] = {}
    for name, genes in GROUPS.items():
        ev = _evaluator(log, params, genes, spec)
        x0 = np.array([get_value(params, g) for g in genes])
        r = ev(np.array([x0] + [x0 * k for k in factors]))
        out[name] = [{"k": k, "rise": float(r[1 + i] / r[0] - 1.0)} for i, k in enumerate(factors)]
    return out


def inertia_ridge(log: FlightLog, params: AircraftParams, spec: TuneSpec,
                  factors: tuple[float, ...] = (0.5, 2.0)) -> list[dict[str, float]]:
    """Fitness with all inertias and all moment coefficients scaled by ``k`` together,
    and with the inertias alone scaled by ``k`` (relative to the unscaled fitness)."""
    inert = ("ixx", "iyy", "izz", "ixz")
    names = inert + MOMENT_COEFFS
    ev = _evaluator(log, params, names, spec)
    x0 = np.array([get_value(params, g) for g in names])
    xs = [x0]
    for k in factors:
        xs.append(x0 * k)
        alone = x0.copy()
        alone[:len(inert)] *= k
        xs.append(alone)
    r = ev(np.array(xs))
    return [{"k": k, "both": float(r[1 + 2 * i] / r[0]), "inertia_only": float(r[2 + 2 * i] / r[0])}
            for i, k in enumerate(factors)]
