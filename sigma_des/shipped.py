"""The example scenarios shipped inside the package, runnable by name.

``sigma-des compare latency_tolerance`` runs ``sigma_des/scenarios/latency_tolerance.toml``
from any directory (a checkout also reaches them as ``scenarios/<name>.toml``). A
scenario argument that names an existing file is that file; otherwise a bare name
(with or without ``.toml``) of a shipped scenario is the shipped file.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["DIR", "names", "resolve"]

#: Where the shipped scenario files live (package data).
DIR = Path(__file__).resolve().parent / "scenarios"


def names() -> list[str]:
    """The names of the shipped scenarios, sorted."""
    return sorted(p.stem for p in DIR.glob("*.toml"))


def resolve(arg: str | Path) -> Path:
    """The file a scenario argument means: an existing path, else a shipped scenario's.

    A name that is neither is returned unchanged (reading it then fails naming it).
    """
    p = Path(arg)
    if p.exists() or len(p.parts) != 1:
        return p
    shipped = DIR / (p.name if p.suffix == ".toml" else f"{p.name}.toml")
    return shipped if shipped.is_file() else p
