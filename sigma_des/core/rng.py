"""Counter-based random streams.

Every random number in sigma_des is a pure function of ``(root seed, stream name,
integer ids…)``: a stream name is hashed to a 64-bit key, the ids are mixed into it
with the SplitMix64 finaliser, and the result is mapped to a uniform on (0, 1).
Nothing is drawn sequentially, so a run's results do not depend on the order in
which simultaneous events happen to be processed, and the per-message and the
batched engines see the very same numbers for the same (stream, entity, index).

All draws go through numpy arrays (even single ones) so that scalar and
vectorised callers execute the same ufunc loops and get bit-identical floats. The
integer hash itself is exact arithmetic modulo 2**64, so :func:`mix` may compute it
in Python integers or compiled code (its common shape) and give the same bits.
"""

from __future__ import annotations

import hashlib
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["RandomStreams", "Stream", "mix", "mix_int"]

#: An array of hashes or one hash (compiled kernels).
_U = TypeVar("_U", np.uint64, NDArray[np.uint64])
#: SplitMix64's constants, shared with the compiled draws (:mod:`sigma_des.core.counter_rng`).
M1 = np.uint64(0xBF58476D1CE4E5B9)
M2 = np.uint64(0x94D049BB133111EB)
GOLDEN = np.uint64(0x9E3779B97F4A7C15)
S30 = np.uint64(30)
S27 = np.uint64(27)
S31 = np.uint64(31)
S11 = np.uint64(11)
TWO53 = 1.0 / 9007199254740992.0


def finalise(z: _U) -> _U:
    """SplitMix64's finaliser, for arrays here and for scalars in compiled kernels."""
    z = (z ^ (z >> S30)) * M1
    z = (z ^ (z >> S27)) * M2
    return z ^ (z >> S31)


_MASK = (1 << 64) - 1
_I64 = (-(1 << 63), 1 << 63)


def _fin_int(z: int) -> int:
    """:func:`finalise` in Python integers modulo 2**64 (the same bits)."""
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK
    return z ^ (z >> 31)


def _absorb_int(h: int, i: int) -> int:
    """One step of :func:`mix` in Python integers modulo 2**64 (the same bits)."""
    return _fin_int(h ^ (((i + 1) * 0x9E3779B97F4A7C15) & _MASK))


def mix_int(key: int | np.uint64, *ids: int) -> int:
    """``int(mix(key, *ids)[0])`` for scalar ids: in Python integers modulo 2**64, the
    same SplitMix64 steps without an array (a seed's derivation, microseconds); an id
    outside the int64 range goes through :func:`mix` itself."""
    h = int(key)
    for i in ids:
        if not _I64[0] <= int(i) < _I64[1]:
            return int(mix(key, *ids)[0])
        h = _absorb_int(h, int(i))
    return _fin_int(h)


def _mix_column(key: int | np.uint64, ids: tuple[ArrayLike, ...]) -> NDArray[np.uint64] | None:
    """:func:`mix` compiled when ``ids`` are int64-range scalars around one 1-d integer
    array (the draw tables' ``(kind, subjects, index, attempt)``); None otherwise."""
    col = -1
    for j, i in enumerate(ids):
        if isinstance(i, np.ndarray):
            if col >= 0 or i.ndim != 1 or i.dtype.kind != "i":
                return None
            col = j
        elif not (isinstance(i, int | np.integer) and _I64[0] <= int(i) < _I64[1]):
            return None
    if col < 0:
        return None
    from sigma_des.core.counter_rng import mix_column  # numba: imported on first use

    h = int(key)
    for i in ids[:col]:
        h = _absorb_int(h, int(i))  # type: ignore[arg-type]
    tail = np.array([int(i) for i in ids[col + 1:]], dtype=np.int64)  # type: ignore[arg-type]
    arr = np.ascontiguousarray(ids[col], dtype=np.int64)
    return mix_column(np.uint64(h), arr, tail)  # type: ignore[no-any-return]


def _mix_outer(key: int | np.uint64, ids: tuple[ArrayLike, ...]) -> NDArray[np.uint64] | None:
    """:func:`mix` compiled when ``ids`` are int64-range scalars and two integer arrays,
    a row ``(1, n)`` and a column ``(m, 1)`` in either order (a block of the draw tables'
    keys: subjects by indices or attempts); None otherwise."""
    pos = [j for j, i in enumerate(ids) if isinstance(i, np.ndarray)]
    if len(pos) != 2:
        return None
    p, q = pos
    x, y = ids[p], ids[q]
    assert isinstance(x, np.ndarray) and isinstance(y, np.ndarray)
    if x.dtype.kind != "i" or y.dtype.kind != "i" or x.ndim != 2 or y.ndim != 2:
        return None
    row_first = x.shape[0] == 1 and y.shape[1] == 1  # (1, n) then (m, 1)
    if not (row_first or (x.shape[1] == 1 and y.shape[0] == 1)):
        return None
    rest = [i for j, i in enumerate(ids) if j not in (p, q)]
    if not all(isinstance(i, int | np.integer) and _I64[0] <= int(i) < _I64[1] for i in rest):
        return None
    from sigma_des.core.counter_rng import mix_outer  # numba: imported on first use

    h = int(key)
    for i in ids[:p]:
        h = _absorb_int(h, int(i))  # type: ignore[arg-type]
    mid = np.array([int(i) for i in ids[p + 1:q]], dtype=np.int64)  # type: ignore[arg-type]
    tail = np.array([int(i) for i in ids[q + 1:]], dtype=np.int64)  # type: ignore[arg-type]
    return mix_outer(np.uint64(h), np.ascontiguousarray(x.ravel(), dtype=np.int64), mid,  # type: ignore[no-any-return]
                     np.ascontiguousarray(y.ravel(), dtype=np.int64), tail, row_first)


def mix(key: int | np.uint64, *ids: ArrayLike) -> NDArray[np.uint64]:
    """Hash a 64-bit key and any number of integer id arrays (broadcast together).

    Scalars around one 1-d array (the per-frame draw fills), or around a row and a column
    (a block of them), are hashed in compiled code
    (:func:`sigma_des.core.counter_rng.mix_column`, ``mix_outer``), the same SplitMix64
    steps modulo 2**64, so the bits are those of the numpy path.

    Args:
        key: the stream key.
        *ids: integer ids (scalars or arrays); negative ids are allowed.

    Returns:
        A uint64 array of the broadcast shape (at least 1-d).
    """
    fast = _mix_column(key, ids)
    if fast is None:
        fast = _mix_outer(key, ids)
    if fast is not None:
        return fast
    arrays = [np.atleast_1d(np.asarray(i)).astype(np.int64).view(np.uint64) for i in ids]
    shape = np.broadcast_shapes(*(a.shape for a in arrays)) if arrays else (1,)
    h = np.full(shape, np.uint64(key), dtype=np.uint64)
    for a in arrays:
        h = finalise(h ^ ((a + np.uint64(1)) * GOLDEN))
    return finalise(h)


def _key_of(seed: int, name: str) -> np.uint64:
    digest = hashlib.blake2b(f"{seed}\x00{name}".encode(), digest_size=8).digest()
    return np.uint64(int.from_bytes(digest, "little"))


class Stream:
    """One named stream: draws are functions of integer ids, never of call order."""

    __slots__ = ("name", "key")

    def __init__(self, seed: int, name: str) -> None:
        self.name = name
        self.key = _key_of(seed, name)

    def uniform(self, *ids: ArrayLike) -> NDArray[np.float64]:
        """Uniform draws on the open interval (0, 1), one per broadcast id tuple."""
        z = mix(self.key, *ids)
        return ((z >> S11).astype(np.float64) + 0.5) * TWO53

    def normal(self, *ids: ArrayLike) -> NDArray[np.float64]:
        """Standard normal draws (inverse CDF of :meth:`uniform`)."""
        from scipy.special import ndtri  # here: SciPy is slow to import (the CLI's start)

        return np.asarray(ndtri(self.uniform(*ids)), dtype=np.float64)

    def exponential(self, *ids: ArrayLike) -> NDArray[np.float64]:
        """Unit-rate exponential draws."""
        return -np.log1p(-self.uniform(*ids))

    def truncated_normal(
        self, mean: float, std: float, low: float, *ids: ArrayLike
    ) -> NDArray[np.float64]:
        """Normal(mean, std) conditioned on ``x >= low`` (exact inverse-CDF truncation)."""
        from scipy.special import ndtr, ndtri

        u = self.uniform(*ids)
        if std == 0.0:
            return np.full(u.shape, max(mean, low))
        a = float(ndtr((low - mean) / std))
        x = mean + std * ndtri(a + u * (1.0 - a))
        return np.maximum(np.asarray(x, dtype=np.float64), low)

    def __repr__(self) -> str:
        return f"Stream({self.name!r})"


class RandomStreams:
    """Factory of named :class:`Stream` objects under one root seed."""

    def __init__(self, seed: int) -> None:
        self.seed = int(seed)
        self._cache: dict[str, Stream] = {}
        #: the key hash with the seed's part absorbed (a stream's key hashes its name on)
        self._prefix = hashlib.blake2b(f"{self.seed}\x00".encode(), digest_size=8)

    def stream(self, name: str) -> Stream:
        """The stream called ``name`` (created on first use, then cached)."""
        s = self._cache.get(name)
        if s is None:
            s = self._cache[name] = Stream.__new__(Stream)
            s.name = name
            h = self._prefix.copy()  # the hash of f"{seed}\x00{name}", as _key_of's
            h.update(name.encode())
            s.key = np.uint64(int.from_bytes(h.digest(), "little"))
        return s

    def __reduce__(self) -> tuple[type[RandomStreams], tuple[int]]:
        # a copy under the same seed (the hash object does not pickle; streams are
        # pure functions of the seed and their name)
        return RandomStreams, (self.seed,)
