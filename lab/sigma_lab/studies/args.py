"""The common command line of the paper-study scripts in ``experiments/``.

Every study script takes ``--quick``, ``--seeds``, ``--out``, ``--jobs`` and
``--progress`` (:func:`study_parser`); :func:`finish_args` fills in the default
seeds and :func:`command_line` records the command in ``summary.json``.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

__all__ = ["command_line", "finish_args", "parse_args", "parse_seeds", "study_parser"]


def parse_seeds(text: str) -> list[int]:
    """Parse ``1,2,3`` or ``1-5`` (or a mix, ``1,4-6``) into a list of seeds.

    Raises:
        argparse.ArgumentTypeError: on an empty or malformed list.
    """
    seeds: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if not part:
                continue
            if "-" in part:
                a, b = part.split("-", 1)
                seeds.extend(range(int(a), int(b) + 1))
            else:
                seeds.append(int(part))
    except ValueError:
        raise argparse.ArgumentTypeError(f"bad seed list {text!r}; use e.g. 1,2,3") from None
    if not seeds or any(s < 0 for s in seeds):
        raise argparse.ArgumentTypeError(f"bad seed list {text!r}; use e.g. 1,2,3")
    return list(dict.fromkeys(seeds))


def study_parser(
    name: str, doc: str | None, default_seeds: str = "1,2,3"
) -> argparse.ArgumentParser:
    """The common command line of a study script.

    Args:
        name: the study name; the default output directory is ``out/<name>``.
        doc: the script's module docstring (shown by ``--help``).
        default_seeds: seeds used when ``--seeds`` is not given.
    """
    p = argparse.ArgumentParser(
        prog=f"experiments/{name}.py",
        description=doc,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="a small, fast version (a few seconds; used by the test suite)",
    )
    p.add_argument(
        "--seeds",
        type=parse_seeds,
        default=None,
        help=f"root seeds, e.g. 1,2,3 or 1-5 (default: {default_seeds}; --quick: the first)",
    )
    p.add_argument("--out", type=Path, default=Path("out") / name, help="output directory")
    p.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="run this many (variant, seed) cases in parallel processes (default 1)",
    )
    p.add_argument("--progress", action="store_true", help="show progress bars on stderr")
    p.set_defaults(default_seeds=default_seeds, study=name)
    return p


def finish_args(args: argparse.Namespace) -> argparse.Namespace:
    """Fill in the default seeds (``--quick`` uses only the first)."""
    if args.seeds is None:
        seeds = parse_seeds(args.default_seeds)
        args.seeds = seeds[:1] if args.quick else seeds
    if args.jobs < 1:
        raise SystemExit("--jobs must be >= 1")
    return args


def parse_args(
    name: str, doc: str | None, argv: list[str] | None, default_seeds: str = "1,2,3"
) -> argparse.Namespace:
    """Parse a study script's command line (:func:`study_parser`, :func:`finish_args`)."""
    return finish_args(study_parser(name, doc, default_seeds).parse_args(argv))


def command_line(name: str) -> str:
    """The command that is running now, as a copy-pasteable string."""
    return shlex.join(["python", f"experiments/{name}.py", *sys.argv[1:]])
