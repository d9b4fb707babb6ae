"""Exceptions shared by every layer."""

from __future__ import annotations

__all__ = ["ConfigError"]


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
