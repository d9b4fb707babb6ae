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

__all__ = ["EXTRAS", "ExtraImportError", "MissingExtra", "missing_extra", "need",
           "need_import"]

#: Top-level module -> the extras that install it (the first is named by default).
EXTRAS: dict[str, tuple[str, ...]] = {
    "orjson": ("record",),
    "mcap": ("record",),
    "dask": ("experiments",),
    "distributed": ("experiments",),
    "matplotlib": ("experiments",),
    "pandas": ("experiments", "live", "record"),
    "jsbsim": ("physics",),
    "paho": ("live",),
    "deap": ("tuning",),
    "pettingzoo": ("env",),
    "gymnasium": ("env",),
}


class MissingExtra(ConfigError):
    """A feature needs an optional package that is not installed.

    Attributes:
        module: the missing top-level module.
        extra: the extra that installs it.
        instead: what the user may do instead (e.g. ``pass --no-plots``), or empty.
    """

    def __init__(self, what: str, module: str, extra: str = "", instead: str = "") -> None:
        self.module = module
        self.extra = extra or EXTRAS[module][0]
        self.instead = instead
        super().__init__(what, f"needs the optional package {module!r}, which is not installed: "
                               f"pip install 'sigma-des[{self.extra}]'"
                               + (f", or {instead}" if instead else ""))

    def __reduce__(self) -> tuple[type[MissingExtra], tuple[str, str, str, str]]:  # type: ignore[override]
        return type(self), (self.key, self.module, self.extra, self.instead)


def need(what: str, *modules: str, extra: str = "", instead: str = "") -> None:
    """Check that ``modules`` can be imported (without importing them).

    Args:
        what: the feature, as the user named it (``--record``, ``sweep``, ...).
        modules: top-level modules of :data:`EXTRAS`.
        extra: the extra to name (default: the module's first in :data:`EXTRAS`).
        instead: what the user may do instead, appended to the message.

    Raises:
        MissingExtra: for the first module that is not installed.
    """
    for m in modules:
        if importlib.util.find_spec(m) is None:
            raise MissingExtra(what, m, extra, instead)


class ExtraImportError(ModuleNotFoundError):
    """Importing a module of an extra (``sigma_des.record``, ``sigma_des.env``) without
    that extra installed: an :class:`ImportError` whose message names the extra to
    install (``name`` is the missing package, so the CLI words it as :func:`need`)."""


def need_import(package: str, *modules: str, extra: str) -> None:
    """At the top of ``package``'s ``__init__``: its extra's ``modules`` must be importable.

    Raises:
        ExtraImportError: naming ``package``, the first missing module and ``extra``.
    """
    for m in modules:
        if importlib.util.find_spec(m) is None:
            raise ExtraImportError(f"{package} needs the optional package {m!r}, which is not "
                                   f"installed: pip install 'sigma-des[{extra}]'", name=m)


def missing_extra(e: ModuleNotFoundError, what: str, extra: str = "") -> MissingExtra | None:
    """``e`` as a :class:`MissingExtra` if it names a package of an extra, else None.

    ``extra`` is named if it is one of the module's extras (a command's own extra).
    """
    top = (e.name or "").split(".")[0]
    if top not in EXTRAS:
        return None
    return MissingExtra(what, top, extra if extra in EXTRAS[top] else "")
