"""Command-line piece of the recorder: the ``compare --record FILE.mcap`` check."""

from __future__ import annotations

from pathlib import Path

from sigma_des.errors import ConfigError

__all__ = ["check_record_path"]


def check_record_path(path: str) -> None:
    """``--record FILE.mcap``: the name ends in ``.mcap`` and its folder exists.

    Raises:
        ConfigError: naming ``--record`` and the problem.
    """
    p = Path(path)
    if p.suffix != ".mcap":
        raise ConfigError("--record", f"{path}: the file name must end in .mcap")
    if not p.parent.is_dir():
        raise ConfigError("--record", f"{path}: folder {p.parent} does not exist")
    if p.is_dir():
        raise ConfigError("--record", f"{path}: is a folder")

