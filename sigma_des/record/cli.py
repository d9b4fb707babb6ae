"""Command-line piece of the recorder: the ``--record FILE.mcap`` check.

``compare`` (CLI and :func:`sigma_des.api.compare`) and ``live`` call it before any
work, so a recording that could not be written costs nothing.
"""

from __future__ import annotations

from pathlib import Path

from sigma_des.errors import ConfigError
from sigma_des.guard import output_file

__all__ = ["check_record_path"]


def check_record_path(path: str | Path, key: str = "--record") -> Path:
    """``--record FILE.mcap``: the name ends in ``.mcap``, its folder exists and accepts
    a new file (a probe file is created and removed there).

    Returns:
        The path.

    Raises:
        ConfigError: naming ``key`` and the problem (a folder, a missing folder,
            ``/proc``, a read-only file system, no permission…).
    """
    p = Path(path)
    if p.suffix != ".mcap":
        raise ConfigError(key, f"{path}: the file name must end in .mcap")
    if not p.parent.is_dir():
        raise ConfigError(key, f"{path}: folder {p.parent} does not exist")
    if p.is_dir():
        raise ConfigError(key, f"{path}: is a folder")
    return output_file(p, key)
