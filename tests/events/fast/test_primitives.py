"""Primitives of the compiled core that are pure functions of their arguments."""

from __future__ import annotations

import pytest

from sigma_des.events.fast.primitives import row_of


@pytest.mark.parametrize("rows", [1, 2, 7, 64, 512, 1000])
def test_row_of_is_pythons_floor_modulo(rows: int) -> None:
    # power-of-two row counts take the mask, the others the division: both must give
    # Python's % for every index, negative ones included
    for index in [*range(-2 * rows - 3, 2 * rows + 3), 2**40 + 5, -(2**40) - 5]:
        assert row_of(index, rows) == index % rows
