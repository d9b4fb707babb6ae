"""Optional extras: which ``pip install 'sigma-des[...]'`` brings a missing package.

A plain ``pip install sigma-des`` runs ``compare``, ``config`` and ``warmup``; the
other features need an extra (pyproject.toml). A feature checks its packages up
front with :func:`need` (before any work), and ``sigma-des`` turns a missing one met
later (:func:`missing_extra`) into the same one-line error, exit status 2, never a
traceback.
"""

from __future__ import annotations

import importlib.util

from sigma_des.errors import ConfigError

__all__ = ["EXTRAS", "MissingExtra", "missing_extra", "need"]

#: Top-level module -> the extra that installs it.
EXTRAS: dict[str, str] = {
    "orjson": "record",
    "mcap": "record",
    "dask": "experiments",
    "distributed": "experiments",
    "matplotlib": "experiments",
    "pandas": "experiments",
    "jsbsim": "physics",
    "paho": "live",
    "deap": "tuning",
    "pettingzoo": "env",
    "gymnasium": "env",
}


class MissingExtra(ConfigError):
    """A feature needs an optional package that is not installed.

    Attributes:
        module: the missing top-level module.
        extra: the extra that installs it.
    """

    def __init__(self, what: str, module: str) -> None:
        self.module = module
        self.extra = EXTRAS[module]
        super().__init__(what, f"needs the optional package {module!r}, not installed: "
                               f"pip install 'sigma-des[{self.extra}]'")

    def __reduce__(self) -> tuple[type[MissingExtra], tuple[str, str]]:  # type: ignore[override]
        return type(self), (self.key, self.module)


def need(what: str, *modules: str) -> None:
    """Check that ``modules`` can be imported (without importing them).

    Args:
        what: the feature, as the user named it (``--record``, ``sweep``, ...).
        modules: top-level modules of :data:`EXTRAS`.

    Raises:
        MissingExtra: the first module that is not installed.
    """
    for m in modules:
        if importlib.util.find_spec(m) is None:
            raise MissingExtra(what, m)


def missing_extra(e: ModuleNotFoundError, what: str) -> MissingExtra | None:
    """``e`` as a :class:`MissingExtra` if it names a package of an extra, else None."""
    top = (e.name or "").split(".")[0]
    return MissingExtra(what, top) if top in EXTRAS else None
