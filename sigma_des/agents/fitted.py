"""Fitted parameter files: what ``sigma-des tune`` writes and ``dynamics_params`` reads.

The aircraft's parameters by name live here too (:data:`PARAM_NAMES`,
:func:`get_value`, :func:`with_values`): the scenario reads fitted files, so they sit
below it, and the tuner (:mod:`sigma_des.tuning`) takes its genes from them.

Format (TOML)::

    dynamics = "quadrotor"          # the preset the values apply to
    [params]                        # parameter name = fitted value (PARAM_NAMES)
    ixx = 0.0191
    rotor_pitch = 0.3012
    "gains.k_att" = 4.5             # autopilot gains: "gains.<key>" (optional)
    [provenance]                    # optional, free-form: seed, log, fitness, version
    seed = 1

Every other parameter keeps the preset's value. A scenario uses the file with
``dynamics = "quadrotor"`` and ``dynamics_params = "fitted.toml"``. A bare name
that is not a file names a fit shipped in ``sigma_des/fits/`` (:func:`shipped_fits`):
``dynamics = "fixedwing"``, ``dynamics_params = "minisgs"`` flies the fixed wing
fitted to JSBSim's minisgs glider (with the preset's propeller).
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import fields
from pathlib import Path
from typing import Any

import tomli_w

from sigma_des.agents.params import AeroCoeffs, AircraftParams
from sigma_des.agents.presets import preset
from sigma_des.errors import ConfigError
from sigma_des.guard import read_text

__all__ = ["KINDS", "PARAM_NAMES", "FITS_DIR", "fitted_params", "get_value", "read_fitted",
           "resolve_fitted", "shipped_fits", "with_values", "write_fitted"]

#: Where the shipped fitted files live (package data).
FITS_DIR = Path(__file__).resolve().parent.parent / "fits"

#: Presets a fitted file may apply to.
KINDS: tuple[str, ...] = ("quadrotor", "fixedwing")

_TOP = tuple(f.name for f in fields(AircraftParams)
             if f.type in ("float", float) and f.name not in ("altitude", "spacing",
                                                              "max_substep", "v_cruise"))
_AERO = tuple(f.name for f in fields(AeroCoeffs))
#: Every parameter a fitted file (or a tuning gene) may set: the float fields of
#: :class:`AircraftParams` and of its :class:`AeroCoeffs`, by bare name.
PARAM_NAMES: tuple[str, ...] = _TOP + _AERO
#: A fitted file may also set the preset's autopilot gains, as ``"gains.<key>"``.
GAIN_PREFIX = "gains."


def get_value(p: AircraftParams, name: str) -> float:
    """Current value of parameter ``name`` (top-level, aerodynamic or ``gains.<key>``)."""
    if name in _TOP:
        return float(getattr(p, name))
    if name in _AERO:
        return float(getattr(p.aero, name))
    if name.startswith(GAIN_PREFIX) and name[len(GAIN_PREFIX):] in p.gains:
        return float(p.gains[name[len(GAIN_PREFIX):]])
    raise ConfigError(name, f"unknown parameter; allowed: {', '.join(PARAM_NAMES)}, "
                      f"or gains.<key> ({', '.join(sorted(p.gains))})")


def with_values(p: AircraftParams, values: dict[str, float]) -> AircraftParams:
    """A copy of ``p`` with the named parameters replaced (validated)."""
    top = {k: float(v) for k, v in values.items() if k in _TOP}
    aero = {k: float(v) for k, v in values.items() if k in _AERO}
    gains = {k[len(GAIN_PREFIX):]: float(v) for k, v in values.items()
             if k.startswith(GAIN_PREFIX) and k[len(GAIN_PREFIX):] in p.gains}
    bad = sorted(set(values) - set(top) - set(aero) - {GAIN_PREFIX + k for k in gains})
    if bad:
        raise ConfigError(bad[0], f"unknown parameter; allowed: {', '.join(PARAM_NAMES)}, "
                          f"or gains.<key> ({', '.join(sorted(p.gains))})")
    if aero:
        top["aero"] = dataclasses.replace(p.aero, **aero)  # type: ignore[assignment]
    if gains:
        top["gains"] = {**p.gains, **gains}  # type: ignore[assignment]
    return dataclasses.replace(p, **top)  # type: ignore[arg-type]


def write_fitted(path: str | Path, kind: str, values: dict[str, float],
                 provenance: dict[str, Any] | None = None) -> Path:
    """Write a fitted parameter file (see module docstring)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    doc: dict[str, Any] = {"dynamics": kind, "params": {k: float(v) for k, v in values.items()}}
    if provenance:
        doc["provenance"] = provenance
    path.write_text("# sigma-des tune: fitted parameters (sigma_des/agents/fitted.py)\n"
                    + tomli_w.dumps(doc))
    return path


def shipped_fits() -> list[str]:
    """Names of the fitted files shipped with the package, sorted."""
    return sorted(p.stem for p in FITS_DIR.glob("*.toml"))


def resolve_fitted(path: str | Path) -> Path:
    """An existing file, else the shipped fit of that bare name (else ``path`` unchanged)."""
    p = Path(path)
    if p.exists() or len(p.parts) != 1:
        return p
    shipped = FITS_DIR / (p.name if p.suffix == ".toml" else f"{p.name}.toml")
    return shipped if shipped.is_file() else p


def read_fitted(path: str | Path) -> tuple[str, dict[str, float]]:
    """``(kind, values)`` of a fitted file or shipped fit (ConfigError names file and key)."""
    p = resolve_fitted(path)
    src = str(p)
    text = read_text(p, src, "fitted parameter file")
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(src, f"not valid TOML: {e}") from None
    for k in doc:
        if k not in ("dynamics", "params", "provenance"):
            raise ConfigError(f"{src}: {k}", "unknown key; allowed: dynamics, params, provenance")
    kind = doc.get("dynamics")
    if kind not in KINDS:
        raise ConfigError(f"{src}: dynamics", f"must be one of {KINDS}, got {kind!r}")
    if "params" not in doc:  # else the preset would fly, silently
        raise ConfigError(f"{src}: params", "missing: a fitted file holds a [params] table of "
                          "name = fitted value (what `sigma-des tune` writes)")
    params = doc["params"]
    if not isinstance(params, dict):
        raise ConfigError(f"{src}: params", "must be a table of name = value")
    if not params:
        raise ConfigError(f"{src}: params", "is empty: a fitted file holds at least one "
                          f"fitted value; allowed names: {', '.join(PARAM_NAMES)}")
    values: dict[str, float] = {}
    for k, v in params.items():
        if k not in PARAM_NAMES and not k.startswith(GAIN_PREFIX):
            raise ConfigError(f"{src}: params.{k}",
                              f"unknown parameter; allowed: {', '.join(PARAM_NAMES)}")
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise ConfigError(f"{src}: params.{k}", f"must be a finite number, got {v!r}")
        values[k] = float(v)
    fitted_params_of(kind, values, src)
    return kind, values


def fitted_params_of(kind: str, values: dict[str, float], src: str = "") -> AircraftParams:
    """The preset ``kind`` with ``values`` applied (ConfigError if not a valid aircraft)."""
    try:
        return with_values(preset(kind), values)
    except ConfigError as e:
        raise ConfigError(f"{src}: params", f"not a valid {kind}: {e}") from None


def fitted_params(path: str | Path, kind: str | None = None) -> AircraftParams:
    """The aircraft of a fitted file; ``kind`` (if given) must match its ``dynamics``."""
    k, values = read_fitted(path)
    if kind is not None and k != kind:
        raise ConfigError(f"{path}: dynamics", f"is {k!r} but the scenario flies {kind!r}")
    return fitted_params_of(k, values, str(path))
