"""Base-latency distributions of a network hop (docs/concepts/model.md, "Network").

A :class:`Dist` is a frozen, validated configuration value that samples
non-negative delays in seconds from a counter-based :class:`~sigma_des.core.rng.Stream`.
Sampling is vectorised: the integer ids (entity, message index, attempt, …) may be
numpy arrays that broadcast together, and a scalar call returns exactly the
element of the corresponding array call (both go through the same ufuncs).

Distributions (field use):

* ``constant`` — ``value``.
* ``uniform`` — ``low`` … ``high``.
* ``normal`` — ``mean``, ``std``; truncated at 0 (conditioned on ``x >= 0``,
  exact inverse-CDF truncation, so ``mean`` is the mean of the *untruncated*
  normal; :meth:`Dist.mean_value` reports the mean of the truncated one).
* ``lognormal`` — ``mean`` and ``std`` of the delay itself (not of its log);
  converted to ``sigma² = ln(1 + std²/mean²)``, ``mu = ln(mean) − sigma²/2``.
* ``exponential`` — ``mean``.
* ``empirical`` — ``file``: samples in seconds, one per line, or the first
  column of a CSV (an optional non-numeric header line is skipped, as are blank
  lines and ``#`` comments). Resampled uniformly, ``samples[floor(u·len)]``.
  Files are loaded once per (path, modification time) and cached.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sigma_des.core.rng import Stream
from sigma_des.errors import ConfigError

__all__ = ["DIST_NAMES", "Dist", "dist_from", "load_samples"]

#: Allowed values of :attr:`Dist.dist`.
DIST_NAMES: tuple[str, ...] = (
    "constant",
    "uniform",
    "normal",
    "lognormal",
    "exponential",
    "empirical",
)


#: The largest delay parameter accepted (s): a million seconds, far beyond any run.
DELAY_MAX = 1e6


def _nonneg_float(name: str, value: object) -> float:
    """``value`` as a float, or ConfigError unless it is a real in ``[0, DELAY_MAX]``."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(name, f"must be a number of seconds >= 0, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < 0.0 or v > DELAY_MAX:
        raise ConfigError(name, f"must be >= 0 and <= {DELAY_MAX:g} s, got {value!r}")
    return v


def load_samples(path: str) -> NDArray[np.float64]:
    """The samples (seconds) of an empirical delay file, cached per path and mtime.

    Args:
        path: a text file, one sample per line, or a CSV whose first column holds
            the samples (an optional header line is skipped).

    Returns:
        A read-only float64 array of at least one finite, non-negative sample.

    Raises:
        ConfigError: (key ``file``) if the file is missing, empty or holds a
            negative, non-finite or non-numeric sample.
    """
    full = os.path.abspath(path)
    try:
        mtime = os.stat(full).st_mtime_ns
    except OSError as exc:
        raise ConfigError("file", f"empirical sample file not found: {path!r} ({exc})") from exc
    if os.path.isdir(full):
        raise ConfigError("file", f"{path!r} is a directory, not a sample file")
    try:
        return _load_cached(full, mtime)
    except UnicodeDecodeError as e:
        raise ConfigError(
            "file", f"{path!r} is not a text file (undecodable byte at offset {e.start}); "
            "expected one sample in seconds per line"
        ) from None
    except OSError as e:
        raise ConfigError("file", f"cannot read {path!r}: {e.strerror or e}") from None


@lru_cache(maxsize=64)
def _load_cached(path: str, mtime_ns: int) -> NDArray[np.float64]:
    del mtime_ns  # part of the cache key only
    values: list[float] = []
    with open(path, encoding="utf-8") as fh:
        for lineno, raw in enumerate(fh, start=1):
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            cell = line.split(",")[0].strip().strip('"')
            try:
                v = float(cell)
            except ValueError:
                if not values and lineno == 1:
                    continue  # header
                raise ConfigError(
                    "file", f"{path}:{lineno}: not a number of seconds: {cell!r}"
                ) from None
            if not math.isfinite(v) or v < 0.0 or v > DELAY_MAX:
                raise ConfigError("file", f"{path}:{lineno}: samples must be >= 0 and "
                                          f"<= {DELAY_MAX:g} s, got {v!r}")
            values.append(v)
    if not values:
        raise ConfigError("file", f"{path}: no samples")
    arr = np.asarray(values, dtype=np.float64)
    arr.setflags(write=False)
    return arr


def _broadcast_shape(ids: tuple[ArrayLike, ...]) -> tuple[int, ...]:
    """The (at least 1-d) shape that :meth:`Stream.uniform` returns for ``ids``."""
    if not ids:
        return (1,)
    return np.broadcast_shapes(*(np.atleast_1d(np.asarray(i)).shape for i in ids))


@dataclass(frozen=True)
class Dist:
    """A non-negative delay distribution in seconds (see the module docstring).

    Attributes:
        dist: one of :data:`DIST_NAMES`.
        value: the constant delay (``constant``).
        low: lower bound (``uniform``).
        high: upper bound (``uniform``).
        mean: mean (``normal`` before truncation, ``lognormal``, ``exponential``).
        std: standard deviation (``normal`` before truncation, ``lognormal``).
        file: path of the sample file (``empirical``).
    """

    dist: str = "constant"
    value: float = 0.0
    low: float = 0.0
    high: float = 0.0
    mean: float = 0.0
    std: float = 0.0
    file: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.dist, str) or self.dist not in DIST_NAMES:
            raise ConfigError("dist", f"must be one of {', '.join(DIST_NAMES)}; got {self.dist!r}")
        for name in ("value", "low", "high", "mean", "std"):
            object.__setattr__(self, name, _nonneg_float(name, getattr(self, name)))
        if not isinstance(self.file, str):
            raise ConfigError("file", f"must be a path string, got {self.file!r}")
        if self.low > self.high:
            raise ConfigError("low", f"must be <= high ({self.high}), got {self.low}")
        if self.dist == "lognormal" and self.std > 0.0 and self.mean == 0.0:
            raise ConfigError("mean", "must be > 0 s for a lognormal with std > 0, got 0")
        if self.dist == "empirical":
            if not self.file:
                raise ConfigError("file", "required (path of a sample file) for dist 'empirical'")
            load_samples(self.file)

    # -- derived quantities ---------------------------------------------------

    def _lognormal_params(self) -> tuple[float, float]:
        sigma2 = math.log1p((self.std / self.mean) ** 2)
        return math.log(self.mean) - 0.5 * sigma2, math.sqrt(sigma2)

    @property
    def is_constant(self) -> bool:
        """True if every sample is the same number (a degenerate distribution)."""
        d = self.dist
        if d == "constant":
            return True
        if d == "uniform":
            return self.low == self.high
        if d in ("normal", "lognormal"):
            return self.std == 0.0
        if d == "exponential":
            return self.mean == 0.0
        samples = load_samples(self.file)
        return bool(np.all(samples == samples[0]))

    def mean_value(self) -> float:
        """The mean delay in seconds (of the truncated distribution for ``normal``)."""
        d = self.dist
        if d == "constant":
            return self.value
        if d == "uniform":
            return 0.5 * (self.low + self.high)
        if d == "normal":
            if self.std == 0.0:
                return self.mean
            from scipy.special import ndtr  # here: SciPy is slow to import (the CLI's start)

            alpha = -self.mean / self.std
            tail = float(ndtr(-alpha))  # P(X >= 0)
            pdf = math.exp(-0.5 * alpha * alpha) / math.sqrt(2.0 * math.pi)
            return self.mean + self.std * pdf / tail
        if d in ("lognormal", "exponential"):
            return self.mean
        return float(np.mean(load_samples(self.file)))

    # -- sampling ---------------------------------------------------------------

    def sample(self, stream: Stream, *ids: ArrayLike) -> NDArray[np.float64]:
        """Delays (s) keyed by ``ids``, one per broadcast id tuple; all ``>= 0``.

        Args:
            stream: the counter-based stream to draw from.
            *ids: integer ids (scalars or arrays, broadcast together).

        Returns:
            A float64 array of the broadcast shape (at least 1-d): :meth:`quantile` of
            the stream's uniforms (none drawn for a degenerate distribution).
        """
        if self.dist == "constant":
            return np.full(_broadcast_shape(ids), self.value)
        return self.quantile(stream.uniform(*ids))

    def quantile(self, u: ArrayLike) -> NDArray[np.float64]:
        """The inverse CDF at ``u`` in (0, 1): what :meth:`sample` returns for uniforms ``u``.

        Exposed so that a caller can build dependent draws with this marginal (the
        host-correlated step times of ``sigma_des.events.jobs``, a Gaussian copula).

        Args:
            u: probabilities in the open interval (0, 1).

        Returns:
            A float64 array of ``u``'s shape (at least 1-d).
        """
        uv = np.atleast_1d(np.asarray(u, dtype=np.float64))
        d = self.dist
        if d == "constant":
            return np.full(uv.shape, self.value)
        if d == "uniform":
            if self.low == self.high:
                return np.full(uv.shape, self.low)
            return self.low + (self.high - self.low) * uv
        if d == "exponential":
            return self.mean * -np.log1p(-uv)
        if d == "empirical":
            samples = load_samples(self.file)
            idx = (uv * samples.size).astype(np.int64)
            np.minimum(idx, samples.size - 1, out=idx)
            return samples[idx]
        if self.std == 0.0:  # a degenerate normal (mean >= 0) or lognormal
            return np.full(uv.shape, self.mean)
        ndtri = _special().ndtri
        # in place: each step the one rounding of ``a + u (1 - a)``, ``mean + std z``,
        # ``mu + sigma z`` (addition and multiplication commute exactly)
        if d == "normal":  # conditioned on x >= 0: exact inverse-CDF truncation
            a = _mass_below_zero(self.mean, self.std)
            x = uv * (1.0 - a)
            x += a
            ndtri(x, out=x)
            x *= self.std
            x += self.mean
            return np.maximum(x, 0.0, out=x)
        mu, sigma = self._lognormal_params()
        z = np.asarray(ndtri(uv), dtype=np.float64)
        z *= sigma
        z += mu
        return np.exp(z, out=z)


def _special() -> Any:
    """``scipy.special``, imported on first use (SciPy is slow to import: the CLI's start)."""
    if not _SPECIAL:
        import scipy.special

        _SPECIAL.append(scipy.special)
    return _SPECIAL[0]


_SPECIAL: list[Any] = []


@lru_cache(maxsize=256)
def _mass_below_zero(mean: float, std: float) -> float:
    """``P(X < 0)`` of Normal(``mean``, ``std``): the truncated normal's ``a`` (kept per
    distribution: the same float every time)."""
    return float(_special().ndtr((0.0 - mean) / std))


_DIST_FIELDS = frozenset(f.name for f in fields(Dist))


def dist_from(value: Any) -> Dist:
    """Build a :class:`Dist` from a config value.

    Args:
        value: a :class:`Dist` (returned as is), a bare number of seconds (a
            constant delay) or a mapping of :class:`Dist` fields.

    Returns:
        The validated distribution.

    Raises:
        ConfigError: for an invalid value, an unknown key or a bad field.
    """
    if isinstance(value, Dist):
        return value
    if isinstance(value, int | float) and not isinstance(value, bool):
        return Dist(dist="constant", value=value)
    if isinstance(value, dict):
        unknown = sorted(set(value) - _DIST_FIELDS)
        if unknown:
            raise ConfigError(
                str(unknown[0]),
                f"unknown key; allowed: {', '.join(sorted(_DIST_FIELDS))}",
            )
        return Dist(**value)
    raise ConfigError("", f"a delay must be a number of seconds or a table, got {value!r}")
