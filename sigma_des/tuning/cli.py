"""``sigma-des tune``: fit the quadrotor or fixed-wing model to a CSV flight log.

``sigma-des tune --dynamics quadrotor --log FLIGHT.csv [--validate OTHER.csv]
[--init START.toml] [--config TUNE.toml] [--set tune.population=48] --out DIR``
writes DIR/fitted.toml (use it with ``--set dynamics_params=DIR/fitted.toml``),
DIR/report.json, DIR/report.md and the fit plots (pipeline.py). Bad input
(missing columns, bad timestamps, NaNs, out-of-range units, bounds with lower >
upper, unknown parameter names or keys) exits with status 2 naming the
column or key.
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path
from typing import Any

from sigma_des.config import parse_set, set_key
from sigma_des.errors import ConfigError
from sigma_des.loading import from_dict

__all__ = ["add_args", "run", "load_spec"]


def add_args(t: argparse.ArgumentParser) -> None:
    """Add the arguments of ``sigma-des tune`` to its subparser ``t``."""
    t.add_argument("--dynamics", required=True, help="quadrotor or fixedwing")
    t.add_argument("--log", required=True, metavar="CSV", help="tuning flight log")
    t.add_argument("--validate", default=None, metavar="CSV", help="held-out validation log")
    t.add_argument("--init", default=None, metavar="TOML",
                   help="starting parameters (fitted-file format; default: the preset)")
    t.add_argument("--config", default=None, metavar="TOML", help="file with a [tune] table")
    t.add_argument("--set", dest="sets", action="append", default=[], metavar="tune.KEY=VALUE",
                   help="override a [tune] key, e.g. --set tune.population=48")
    t.add_argument("--out", required=True, metavar="DIR", help="output directory")


def load_spec(config: str | None, sets: list[str]) -> Any:
    """The TuneSpec of an optional TOML file plus ``tune.*`` overrides."""
    from sigma_des.tuning.spec import TuneSpec

    data: dict[str, Any] = {}
    if config is not None:
        try:
            data = tomllib.loads(Path(config).read_text())
        except FileNotFoundError:
            raise ConfigError(config, "tune config file not found") from None
        except tomllib.TOMLDecodeError as e:
            raise ConfigError(config, f"not valid TOML: {e}") from None
        bad = [k for k in data if k != "tune"]
        if bad:
            raise ConfigError(f"{config}: {bad[0]}", "unknown key; allowed: a [tune] table")
    for item in sets:
        k, v = parse_set(item)
        if not k.startswith("tune."):
            raise ConfigError(k, "only tune.<key> can be set here")
        set_key(data, k, v)
    tune = data.get("tune", {})
    if not isinstance(tune, dict):
        raise ConfigError("tune", "must be a table")
    return from_dict(TuneSpec, tune, "tune")


def run(args: argparse.Namespace) -> int:
    """Run ``sigma-des tune``; returns the exit status (2 on bad input)."""
    try:
        from sigma_des.agents.fitted import KINDS, fitted_params
        from sigma_des.agents.presets import preset
        from sigma_des.tuning.flightlog import read_csv
        from sigma_des.tuning.pipeline import tune_and_report

        if args.dynamics not in KINDS:
            raise ConfigError("--dynamics", f"must be one of {', '.join(KINDS)}, "
                              f"got {args.dynamics!r}")
        spec = load_spec(args.config, args.sets)
        log = read_csv(args.log, args.dynamics)
        val = read_csv(args.validate, args.dynamics) if args.validate else None
        start = fitted_params(args.init, args.dynamics) if args.init else preset(args.dynamics)
        rep = tune_and_report(log, start, spec, args.out, validate=val)
    except ConfigError as e:
        print(f"sigma-des: error: {e}", file=sys.stderr)
        return 2
    from sigma_des.tuning.pipeline import markdown

    print(markdown(rep))
    print(f"wrote {Path(args.out) / 'fitted.toml'} and report.json / report.md")
    return 0
