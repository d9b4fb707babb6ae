"""``sigma-des tune``: fit the quadrotor or fixed-wing model to a CSV flight log.

``sigma-des tune --dynamics quadrotor --log FLIGHT.csv [--validate OTHER.csv]
[--init START.toml] [--config TUNE.toml] [--set tune.population=48] --out DIR``
writes DIR/fitted.toml (use it with ``--set dynamics_params=DIR/fitted.toml``),
DIR/report.json, DIR/report.md and the fit plots (pipeline.py). Bad input
(missing columns, bad timestamps, NaNs, out-of-range units, bounds with lower >
upper, unknown parameter names or keys) exits with status 2 naming the
column or key. Every file is checked before the work starts (:mod:`sigma_des.guard`):
inputs readable UTF-8 text files, ``--out`` a writable folder, and the GA's batched
flights within the available memory (``--force`` overrides); errors name the option.
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path
from typing import Any

from sigma_des.config import parse_set, set_key
from sigma_des.errors import ConfigError
from sigma_des.guard import read_text, require_memory
from sigma_des.loading import from_dict

__all__ = ["add_args", "run", "load_spec", "tune_bytes"]


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
    t.add_argument("--force", action="store_true", help="skip the memory check")


def load_spec(config: str | None, sets: list[str]) -> Any:
    """The TuneSpec of an optional TOML file plus ``tune.*`` overrides."""
    from sigma_des.tuning.spec import TuneSpec

    data: dict[str, Any] = {}
    if config is not None:
        text = read_text(config, "--config", "tune config file")
        try:
            data = tomllib.loads(text)
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


def tune_bytes(log: Any, spec: Any) -> int:
    """Estimated peak memory of the GA: one batched flight of the whole population.

    Each (candidate, window) row holds its simulated states and the logged
    observations over the window (float64): 49 KB per candidate on a 3 s, 100 Hz
    log, which is what the peak RSS grew by per candidate from population 200 to
    4000. Selection briefly holds two generations' arrays, so 1.5 times that is
    reserved (measured: 7.3 GB at population 100000).
    """
    from sigma_des.agents import layout as L
    from sigma_des.tuning.replay import windows

    win = windows(log, spec.segment)
    return int(1.5 * spec.population * win.count * (win.steps + 1) * (L.STATE_DIM + 12) * 8)


def _read_log(path: str, kind: str, option: str) -> Any:
    """A flight log given by ``option``; errors name the option and the file."""
    from sigma_des.tuning.flightlog import read_csv

    try:
        return read_csv(path, kind)
    except ConfigError as e:
        raise ConfigError(f"{option} {e.key}", e.reason) from None


def _start(path: str, kind: str) -> Any:
    """The ``--init`` parameters; errors name the option and the file."""
    from sigma_des.agents.fitted import fitted_params

    try:
        return fitted_params(path, kind)
    except ConfigError as e:
        raise ConfigError(f"--init {e.key}", e.reason) from None


def run(args: argparse.Namespace) -> int:
    """Run ``sigma-des tune``; returns the exit status (2 on bad input)."""
    try:
        from sigma_des.agents.fitted import KINDS
        from sigma_des.agents.presets import preset
        from sigma_des.budget import available_bytes
        from sigma_des.outputs import check_out_dir
        from sigma_des.tuning.pipeline import tune_and_report

        if args.dynamics not in KINDS:
            raise ConfigError("--dynamics", f"must be one of {', '.join(KINDS)}, "
                              f"got {args.dynamics!r}")
        spec = load_spec(args.config, args.sets)
        log = _read_log(args.log, args.dynamics, "--log")
        val = _read_log(args.validate, args.dynamics, "--validate") if args.validate else None
        start = _start(args.init, args.dynamics) if args.init else preset(args.dynamics)
        require_memory(tune_bytes(log, spec), available_bytes(),
                       f"tune.population={spec.population}",
                       "lower tune.population or use a shorter --log", force=args.force)
        check_out_dir(args.out, "--out")
        try:
            rep = tune_and_report(log, start, spec, args.out, validate=val)
        except OSError as e:  # e.g. the disk filled up while writing the report
            raise ConfigError("--out", f"cannot write {args.out}: {e.strerror or e}") from None
    except ConfigError as e:
        print(f"sigma-des: error: {e}", file=sys.stderr)
        return 2
    from sigma_des.tuning.pipeline import markdown

    print(markdown(rep))
    print(f"wrote {Path(args.out) / 'fitted.toml'} and report.json / report.md")
    return 0
