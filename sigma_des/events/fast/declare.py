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
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

__all__ = ["Field", "Plan", "build", "plan", "reusable", "shape_of", "swap"]


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


#: A declaration resolved under one set of dimensions (:func:`plan`): per field its
#: name, dtype, shape and fill.
Plan = tuple[tuple[str, np.dtype[Any], tuple[int, ...], float | None], ...]


def plan(fields: Sequence[Field], dims: Mapping[str, int]) -> Plan:
    """``fields`` resolved under ``dims`` (what :func:`build` reads of them; a caller
    building many tuples of the same dimensions keeps it)."""
    return tuple((f.name, np.dtype(f.dtype), shape_of(f, dims), f.fill) for f in fields)


def _as_plan(fields: Sequence[Field] | Plan, dims: Mapping[str, int]) -> Plan:
    """A declaration resolved under ``dims``, or ``fields`` if it is a plan already."""
    if fields and isinstance(fields[0], Field):
        return plan(cast(Sequence[Field], fields), dims)
    return cast(Plan, fields)


def build(
    fields: Sequence[Field] | Plan, dims: Mapping[str, int],
    given: Mapping[str, NDArray[Any]], spare: Mapping[str, NDArray[Any]] | None = None,
) -> tuple[NDArray[Any], ...]:
    """Build the state tuple of ``fields``: ``given`` arrays checked, the others made
    from their fill (``np.zeros`` for a fill of 0: the same contents).

    Args:
        fields: the declaration, in order, or its :func:`plan` under ``dims``.
        dims: the size of every dimension name the declaration uses (unread for a plan).
        given: the arrays of the fields whose ``fill`` is None (and no others).
        spare: arrays of a state nothing reads any more, by field name: a field with a
            fill takes its spare array, filled again in place, when that has the field's
            dtype and shape and owns its memory (:func:`reusable`); else a new one.

    Returns:
        The state tuple.

    Raises:
        ValueError: a given array is missing, unexpected, or of the wrong dtype or
            shape, or not C-contiguous (numba would copy or reject it).
    """
    p = _as_plan(fields, dims)
    extra = given.keys() - _given_names(p)
    if extra:
        raise ValueError(f"arrays given for fields with a fill: {sorted(extra)}")
    arrays: list[NDArray[Any]] = []
    old = spare if spare is not None else {}
    for name, dtype, shape, fill in p:
        if fill is not None:
            a = old.get(name)
            if a is not None and reusable(a, dtype, shape):
                a.fill(fill)  # the cast np.full makes, into the same bytes
                arrays.append(a)
            else:
                arrays.append(np.zeros(shape, dtype=dtype) if fill == 0
                              else np.full(shape, fill, dtype=dtype))
            continue
        a = given.get(name)
        if a is None:
            raise ValueError(f"state field {name!r}: no array given")
        if a.dtype != dtype or a.shape != shape or not a.flags.c_contiguous:
            raise ValueError(
                f"state field {name!r}: {a.dtype}{a.shape} given, "
                f"{dtype}{shape} C-contiguous declared"
            )
        arrays.append(a)
    return tuple(arrays)


def _given_names(p: Plan) -> frozenset[str]:
    """The fields of plan ``p`` without a fill (kept for the last plans asked about)."""
    hit = _GIVEN.get(id(p))
    if hit is None or hit[0] is not p:
        if len(_GIVEN) >= 64:
            _GIVEN.clear()
        hit = _GIVEN[id(p)] = (p, frozenset(name for name, _, _, fill in p if fill is None))
    return hit[1]


_GIVEN: dict[int, tuple[Plan, frozenset[str]]] = {}


def reusable(a: NDArray[Any], dtype: np.dtype[Any], shape: tuple[int, ...]) -> bool:
    """Whether ``a`` can serve as a new array of ``dtype`` and ``shape``: the same type
    and shape, C-contiguous, writeable, and owning its memory (the core resizes some
    arrays in place, which only an owner can)."""
    f = a.flags
    return (a.dtype == dtype and a.shape == shape and f.c_contiguous and f.writeable
            and f.owndata)


def swap(
    S: tuple[NDArray[Any], ...], index: Mapping[str, int], new: Mapping[str, NDArray[Any]]
) -> tuple[NDArray[Any], ...]:
    """The state ``S`` with the arrays of the fields named in ``new`` replaced
    (``index``: each field's position)."""
    out = list(S)
    for name, a in new.items():
        out[index[name]] = a
    return tuple(out)
