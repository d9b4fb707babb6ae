"""Fitted parameter files: what ``sigma-des tune`` writes and ``dynamics_params`` reads.

Format (TOML)::

    dynamics = "quadrotor"          # the preset the values apply to
    [params]                        # gene name = fitted value (spec.GENE_NAMES)
    ixx = 0.0191
    rotor_pitch = 0.3012
    [provenance]                    # optional, free-form: seed, log, fitness, version
    seed = 1

Every other parameter keeps the preset's value. A scenario uses the file with
``dynamics = "quadrotor"`` and ``dynamics_params = "fitted.toml"``.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import tomli_w

from sigma_des.agents.params import AircraftParams
from sigma_des.agents.presets import preset
from sigma_des.errors import ConfigError
from sigma_des.guard import read_text
from sigma_des.tuning.spec import GENE_NAMES, with_values

__all__ = ["KINDS", "write_fitted", "read_fitted", "fitted_params"]

#: Presets a fitted file may apply to.
KINDS: tuple[str, ...] = ("quadrotor", "fixedwing")


def write_fitted(path: str | Path, kind: str, values: dict[str, float],
                 provenance: dict[str, Any] | None = None) -> Path:
    """Write a fitted parameter file (see module docstring)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    doc: dict[str, Any] = {"dynamics": kind, "params": {k: float(v) for k, v in values.items()}}
    if provenance:
        doc["provenance"] = provenance
    path.write_text("# sigma-des tune: fitted parameters (sigma_des/tuning/fitted.py)\n"
                    + tomli_w.dumps(doc))
    return path


def read_fitted(path: str | Path) -> tuple[str, dict[str, float]]:
    """``(kind, values)`` of a fitted file, validated (ConfigError names file and key)."""
    p = Path(path)
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
    params = doc.get("params", {})
    if not isinstance(params, dict):
        raise ConfigError(f"{src}: params", "must be a table of name = value")
    values: dict[str, float] = {}
    for k, v in params.items():
        if k not in GENE_NAMES:
            raise ConfigError(f"{src}: params.{k}",
                              f"unknown parameter; allowed: {', '.join(GENE_NAMES)}")
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
