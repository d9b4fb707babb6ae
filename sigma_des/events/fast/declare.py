"""A state tuple declared field by field: the declaration's type and how a tuple is built.

The compiled core's state (:data:`~sigma_des.events.fast.layout.FIELDS`) is a plain
tuple of numpy arrays, each declared by a :class:`Field` (name, dtype, shape as names of
dimensions, fill). :func:`build` allocates a tuple from a declaration, checking the
arrays the caller supplies; :func:`swap` replaces named arrays of a built tuple. The
layout module binds both to the core's one declaration (``layout.allocate``,
``layout.replaced``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["Field", "build", "shape_of", "swap"]


@dataclass(frozen=True)
class Field:
    """One array of the core's state.

    Attributes:
        name: the field's name (its constant is the name in capitals).
        dtype: numpy dtype of the array.
        shape: its dimensions, each a dimension name (resolved by :func:`build`)
            or a fixed size.
        fill: initial value of every element, or None: the driver supplies the
            array (parameters, tables it fills, or arrays shared with the engine).
        doc: what the array holds.
    """

    name: str
    dtype: type[np.generic]
    shape: tuple[str | int, ...]
    fill: float | None
    doc: str


def shape_of(field: Field, dims: Mapping[str, int]) -> tuple[int, ...]:
    """The shape of ``field`` with its dimension names resolved from ``dims``."""
    return tuple(d if isinstance(d, int) else dims[d] for d in field.shape)


def build(
    fields: Sequence[Field], dims: Mapping[str, int], given: Mapping[str, NDArray[Any]],
    shapes: Sequence[tuple[int, ...]] | None = None,
) -> tuple[NDArray[Any], ...]:
    """Build the state tuple of ``fields``: ``given`` arrays checked, the others made
    from their fill (``np.zeros`` for a fill of 0: the same contents).

    Args:
        fields: the declaration, in order.
        dims: the size of every dimension name the declaration uses.
        given: the arrays of the fields whose ``fill`` is None (and no others).
        shapes: each field's :func:`shape_of` under ``dims``, if the caller has them.

    Returns:
        The state tuple.

    Raises:
        ValueError: a given array is missing, unexpected, or of the wrong dtype or
            shape, or not C-contiguous (numba would copy or reject it).
    """
    extra = set(given) - {f.name for f in fields if f.fill is None}
    if extra:
        raise ValueError(f"arrays given for fields with a fill: {sorted(extra)}")
    arrays: list[NDArray[Any]] = []
    if shapes is None:
        shapes = [shape_of(f, dims) for f in fields]
    for f, shape in zip(fields, shapes, strict=True):
        if f.fill is not None:
            arrays.append(np.zeros(shape, dtype=f.dtype) if f.fill == 0
                          else np.full(shape, f.fill, dtype=f.dtype))
            continue
        if f.name not in given:
            raise ValueError(f"state field {f.name!r}: no array given")
        a = given[f.name]
        if a.dtype != f.dtype or a.shape != shape or not a.flags.c_contiguous:
            raise ValueError(
                f"state field {f.name!r}: {a.dtype}{a.shape} given, "
                f"{np.dtype(f.dtype)}{shape} C-contiguous declared"
            )
        arrays.append(a)
    return tuple(arrays)


def swap(
    S: tuple[NDArray[Any], ...], index: Mapping[str, int], new: Mapping[str, NDArray[Any]]
) -> tuple[NDArray[Any], ...]:
    """The state ``S`` with the arrays of the fields named in ``new`` replaced
    (``index``: each field's position)."""
    out = list(S)
    for name, a in new.items():
        out[index[name]] = a
    return tuple(out)
