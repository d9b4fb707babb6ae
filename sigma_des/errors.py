"""Exceptions shared by every layer."""

from __future__ import annotations

__all__ = ["ConfigError", "ctrl_c_inside"]


class ConfigError(ValueError):
    """A configuration value is unknown, of the wrong type or out of range.

    Attributes:
        key: dotted path of the offending key (e.g. ``net.host_link.loss.p``).
        reason: what is wrong and which values are allowed.
    """

    def __init__(self, key: str, reason: str) -> None:
        self.key = key
        self.reason = reason
        super().__init__(f"{key}: {reason}" if key else reason)

    def __reduce__(self) -> tuple[type[ConfigError], tuple[str, str]]:
        # rebuilt from both fields, so the error survives a worker process's pickling
        return type(self), (self.key, self.reason)

    def under(self, prefix: str) -> ConfigError:
        """The same error with ``prefix.`` prepended to its key."""
        key = f"{prefix}.{self.key}" if self.key else prefix
        return ConfigError(key, self.reason)


def ctrl_c_inside(exc: BaseException) -> bool:
    """True if ``exc`` is a ``KeyboardInterrupt`` or was raised while one propagated
    (its ``__cause__``/``__context__`` chain holds one).

    A Ctrl-C that lands while a numba-compiled function runs Python code of its own
    (numba boxes a freshly allocated array through ``_numba_unpickle``) comes out of the
    compiled call as a ``SystemError`` chained to the ``KeyboardInterrupt``; callers that
    keep finished work on Ctrl-C treat it as the interrupt it was.
    """
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False
