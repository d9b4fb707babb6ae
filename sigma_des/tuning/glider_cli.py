"""``sigma-des flightlog``: write a tuning flight log flown by a JSBSim glider.

``sigma-des flightlog --aircraft minisgs --speed 10 --variant 0 --duration 30
--out tune.csv`` flies :func:`~sigma_des.tuning.glider_log.fly_glider` and writes
the CSV that ``sigma-des tune --dynamics fixedwing --log tune.csv`` reads
(flightlog.py). Held-out logs: another ``--variant`` (input programme) and/or
``--speed`` (trim). Needs the ``physics`` extra (the ``jsbsim`` package); bad
options exit with status 2 naming the option and its allowed range.
"""

from __future__ import annotations

import argparse
import sys

from sigma_des.errors import ConfigError

__all__ = ["add_args", "run"]


def add_args(p: argparse.ArgumentParser) -> None:
    """Add the arguments of ``sigma-des flightlog`` to its subparser ``p``."""
    from sigma_des.tuning.glider_log import GLIDERS, VARIANTS, GlideSpec

    d = GlideSpec()
    p.add_argument("--aircraft", default=d.aircraft, help=f"JSBSim glider ({', '.join(GLIDERS)})")
    p.add_argument("--speed", type=float, default=d.speed, help="trim airspeed, m/s [7, 16]")
    p.add_argument("--speed-step", dest="speed_step", type=float, default=d.speed_step,
                   help="trim-speed change halfway through the log, m/s (default 0)")
    p.add_argument("--duration", type=float, default=d.duration, help="logged time, s [2, 600]")
    p.add_argument("--rate", type=float, default=d.rate, help="control and log rate, Hz [10, 400]")
    p.add_argument("--variant", type=int, default=d.variant,
                   help=f"input programme 0..{VARIANTS - 1} (0 = tuning; others held out)")
    p.add_argument("--seed", type=int, default=d.seed, help="sensor-noise seed")
    p.add_argument("--amp-e", dest="amp_e", type=float, default=d.amp_e,
                   help="elevator excitation amplitude, rad [0, 0.2]")
    p.add_argument("--amp-a", dest="amp_a", type=float, default=d.amp_a,
                   help="aileron excitation amplitude, rad [0, 0.2]")
    p.add_argument("--altitude", type=float, default=d.altitude, help="start altitude, m")
    p.add_argument("--warmup", type=float, default=d.warmup,
                   help="unlogged trimmed glide before the log, s [0, 60]")
    p.add_argument("--no-noise", dest="noise", action="store_false",
                   help="log the exact JSBSim state (default: seeded sensor noise)")
    p.add_argument("--out", required=True, metavar="CSV", help="flight log to write")


def run(args: argparse.Namespace) -> int:
    """Run ``sigma-des flightlog``; returns the exit status (2 on bad input)."""
    from sigma_des.extras import need

    try:
        from sigma_des.tuning.glider_log import GlideSpec

        spec = GlideSpec(aircraft=args.aircraft, speed=args.speed,
                         speed_step=args.speed_step, duration=args.duration,
                         rate=args.rate, variant=args.variant, seed=args.seed,
                         amp_e=args.amp_e, amp_a=args.amp_a, altitude=args.altitude,
                         warmup=args.warmup, noise=args.noise)
        need("flightlog", "jsbsim", extra="physics")
        from sigma_des.tuning.flightlog import write_csv
        from sigma_des.tuning.glider_log import fly_glider

        log = fly_glider(spec)
        try:
            path = write_csv(log, args.out)
        except OSError as e:
            raise ConfigError("--out", f"cannot write {args.out}: {e.strerror or e}") from None
    except ConfigError as e:
        print(f"sigma-des: error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path} ({log.t.shape[0]} rows, {log.source})")
    return 0
