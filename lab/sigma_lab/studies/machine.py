"""What a study's figures were measured on: one description, filed with every result.

The docs' result pages read ``cpu``, ``cores``, ``memory_gb``, ``system`` and
``python``; a study's own ``summary.json`` adds the host name and sigma_des version.
"""

from __future__ import annotations

import os
import platform
import socket
from pathlib import Path
from typing import Any

from sigma_des import __version__

__all__ = ["machine"]


def _cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else what ``platform`` knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def machine() -> dict[str, Any]:
    """CPU model and count, memory (GB), OS, host name, Python and sigma_des versions."""
    mem_gb = None
    try:
        mem_gb = round(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") / 2**30, 1)
    except (ValueError, OSError):
        pass
    return {"cpu": _cpu_model(), "cores": os.cpu_count(), "memory_gb": mem_gb,
            "system": f"{platform.system()} {platform.release()}",
            "host": socket.gethostname(), "python": platform.python_version(),
            "sigma_des": __version__}
