"""``sigma-des replay FILE.mcap --rate HZ [--method M] --out traj.csv`` (module ``cli``).

Every option is checked before any work (:mod:`sigma_des.guard`): the recording is a
readable sigma_des MCAP file, ``--rate`` and ``--window-w`` are within
:data:`MAX_RATE` and :data:`MAX_WINDOW_W`, the output's estimated size fits in the
available memory (``--force`` overrides), and ``--out`` can be written. The CSV is
written under a temporary name, fsynced and renamed, so a full disk never leaves a
truncated ``traj.csv``. Any failure: exit status 2 and one line naming the option.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from sigma_des.errors import ConfigError

__all__ = ["MAX_RATE", "MAX_WINDOW_W", "add_replay_args", "replay_bytes", "run_replay"]

#: Highest output rate (Hz): 1 µs steps, far beyond any recorded dynamics.
MAX_RATE = 1e6
#: Widest tangent window half-width (samples) of eq. (15).
MAX_WINDOW_W = 1000
#: Bytes held per output row: 9 float64 columns, about 4 copies at the peak
#: (interpolation, concatenation, the DataFrame, the CSV text).
_ROW_BYTES = 9 * 8 * 4


def add_replay_args(r: argparse.ArgumentParser) -> None:
    """Add the arguments of ``sigma-des replay`` to its subparser ``r``."""
    from sigma_des.replay.interpolate import INTERP_METHODS
    from sigma_des.replay.window import RULES

    r.add_argument("recording", metavar="FILE.mcap", help="a recording (compare/live --record)")
    r.add_argument("--rate", type=float, required=True, metavar="HZ",
                   help=f"output rate (Hz), in (0, {MAX_RATE:g}]")
    r.add_argument("--method", default="hermite-dw", choices=INTERP_METHODS,
                   help="interpolation method (default hermite-dw)")
    r.add_argument("--methods", default=None,
                   help="comma-separated alignment methods to replay (default: all recorded)")
    r.add_argument("--window", default="none", choices=RULES,
                   help="hermite-dw tangent window rule (default none: recorded states are "
                   "exact; 'both' is eq. (15) in our reading, for noisy logs)")
    r.add_argument("--window-w", type=int, default=1, metavar="W",
                   help=f"default window half-width w of eq. (15), samples, in "
                   f"0..{MAX_WINDOW_W} (default 1)")
    r.add_argument("--out", required=True, metavar="traj.csv", help="output CSV")
    r.add_argument("--force", action="store_true",
                   help="overwrite --out if it exists; skip the memory check")


def replay_bytes(scenario: dict[str, Any], n_methods: int, rate: float) -> int:
    """Estimated peak memory of replaying ``n_methods`` methods of a recording at ``rate``.

    Args:
        scenario: the recording's stored scenario (``nodes``, ``duration``).
        n_methods: methods replayed.
        rate: output rate (Hz).
    """
    nodes = int(scenario.get("nodes", 1))
    duration = float(scenario.get("duration", 0.0))
    rows = n_methods * nodes * (duration * rate + 1.0)
    return int(min(rows * _ROW_BYTES, 2.0**62))


def _check_options(args: argparse.Namespace) -> list[str] | None:
    """Bounds, input, memory and output checks; the methods to replay (None: all)."""
    from sigma_des.budget import available_bytes
    from sigma_des.guard import input_file, output_file, require_memory
    from sigma_des.record.reader import open_recording

    if not (0 < args.rate <= MAX_RATE):  # also refuses NaN
        raise ConfigError("--rate", f"must be in (0, {MAX_RATE:g}] Hz, got {args.rate}")
    if not 0 <= args.window_w <= MAX_WINDOW_W:
        raise ConfigError("--window-w", f"must be in 0..{MAX_WINDOW_W} samples, "
                          f"got {args.window_w}")
    input_file(args.recording, "recording", "recording (MCAP file)")
    rec = open_recording(args.recording)
    methods = None
    if args.methods:
        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
        for m in methods:
            if m not in rec.methods:
                raise ConfigError("--methods", f"{m!r} is not in {args.recording} "
                                  f"(recorded: {', '.join(rec.methods)})")
    n = len(methods) if methods is not None else len(rec.methods)
    require_memory(replay_bytes(rec.scenario, n, args.rate), available_bytes(),
                   f"replay at --rate {args.rate:g} Hz", "lower --rate or pick --methods",
                   force=args.force)
    output_file(args.out, "--out", force=args.force)
    return methods


def run_replay(args: argparse.Namespace) -> int:
    """``sigma-des replay``: exit status 0, or 2 with a message naming the problem."""
    import time

    from sigma_des.guard import atomic_write
    from sigma_des.replay.replay import replay
    from sigma_des.replay.window import WindowRule

    out = Path(args.out)
    try:
        methods = _check_options(args)
        window = WindowRule(rule=args.window, w=args.window_w)
        t0 = time.perf_counter()
        df = replay(args.recording, args.rate, args.method, methods, window)
        t1 = time.perf_counter()
        atomic_write(out, lambda fh: df.to_csv(fh, index=False), "--out")
    except ConfigError as e:
        print(f"sigma-des: error: {e}", file=sys.stderr)
        return 2
    print(f"replayed {df['node'].nunique() if len(df) else 0} nodes x "
          f"{df['method'].nunique() if len(df) else 0} methods, {len(df)} rows at "
          f"{args.rate:g} Hz ({args.method}) in {t1 - t0:.2f} s; wrote {out}")
    return 0
