"""``sigma-des replay FILE.mcap --rate HZ [--method M] --out traj.csv`` (module ``cli``)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from sigma_des.errors import ConfigError

__all__ = ["add_replay_args", "run_replay"]


def add_replay_args(r: argparse.ArgumentParser) -> None:
    """Add the arguments of ``sigma-des replay`` to its subparser ``r``."""
    from sigma_des.replay.interpolate import INTERP_METHODS
    from sigma_des.replay.window import RULES

    r.add_argument("recording", metavar="FILE.mcap", help="a recording (compare/live --record)")
    r.add_argument("--rate", type=float, required=True, metavar="HZ", help="output rate (Hz)")
    r.add_argument("--method", default="hermite-dw", choices=INTERP_METHODS,
                   help="interpolation method (default hermite-dw)")
    r.add_argument("--methods", default=None,
                   help="comma-separated alignment methods to replay (default: all recorded)")
    r.add_argument("--window", default="none", choices=RULES,
                   help="hermite-dw tangent window rule (default none: recorded states are "
                   "exact; 'both' is eq. (15) in our reading, for noisy logs)")
    r.add_argument("--window-w", type=int, default=1, metavar="W",
                   help="default window half-width w of eq. (15), samples (default 1)")
    r.add_argument("--out", required=True, metavar="traj.csv", help="output CSV")
    r.add_argument("--force", action="store_true", help="overwrite --out if it exists")


def run_replay(args: argparse.Namespace) -> int:
    """``sigma-des replay``: exit status 0, or 2 with a message naming the problem."""
    import time

    from sigma_des.replay.replay import replay
    from sigma_des.replay.window import WindowRule

    out = Path(args.out)
    try:
        if not (args.rate > 0 and math.isfinite(args.rate)):
            raise ConfigError("--rate", f"must be a finite number > 0 Hz, got {args.rate}")
        if out.exists() and not args.force:
            raise ConfigError("--out", f"{out}: exists; pass --force to overwrite it")
        if not out.parent.is_dir():
            raise ConfigError("--out", f"{out}: folder {out.parent} does not exist")
        methods = None
        if args.methods:
            methods = [m.strip() for m in args.methods.split(",") if m.strip()]
            from sigma_des.record.reader import open_recording

            have = open_recording(args.recording).methods
            for m in methods:
                if m not in have:
                    raise ConfigError("--methods", f"{m!r} is not in {args.recording} "
                                      f"(recorded: {', '.join(have)})")
        if args.window_w < 0:
            raise ConfigError("--window-w", f"must be >= 0 samples, got {args.window_w}")
        window = WindowRule(rule=args.window, w=args.window_w)
        t0 = time.perf_counter()
        df = replay(args.recording, args.rate, args.method, methods, window)
        t1 = time.perf_counter()
    except ConfigError as e:
        print(f"sigma-des: error: {e}", file=sys.stderr)
        return 2
    df.to_csv(out, index=False)
    print(f"replayed {df['node'].nunique() if len(df) else 0} nodes x "
          f"{df['method'].nunique() if len(df) else 0} methods, {len(df)} rows at "
          f"{args.rate:g} Hz ({args.method}) in {t1 - t0:.2f} s; wrote {out}")
    return 0
