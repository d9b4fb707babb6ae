"""The draw tables' one filler (tables.fill_rows), as DrawTables and AttemptTables use it.

A row is refilled only when it holds another key, from the cache's vector for the
row's (kind, index, attempt); a constant source gets no table.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sigma_des.core.draws import DrawCache
from sigma_des.events.fast.codes import K_STATE, K_TRIGGER, STEP, SVC_PUB
from sigma_des.events.fast.tables import DrawTables, fill_rows
from sigma_des.events.jobs import STEP_DRAW


class Counting:
    """A sampler whose values encode their key: ``kind*1e4 + index*10 + attempt + s/10``."""

    def __init__(self) -> None:
        self.calls: list[tuple[int, int, int]] = []

    def __call__(
        self, subjects: NDArray[np.int64], kind: int, index: int, attempt: int
    ) -> NDArray[np.float64]:
        self.calls.append((kind, index, attempt))
        return kind * 1e4 + index * 10.0 + attempt + subjects / 10.0


def test_fill_rows_fills_missing_rows_once_and_refills_a_taken_row() -> None:
    sampler = Counting()
    cache = DrawCache(2, sampler)
    values = np.zeros((2, 4, 3))
    tags = np.full((2, 4), -1, dtype=np.int64)
    fills = [(0, cache, 5), (1, cache, 7)]
    fill_rows(values, tags, fills, 1, 9, 3, 2)
    assert sampler.calls == [(5, 3, 2), (7, 3, 2)]
    # a short vector fills the head of the row; the rest stays as it was
    assert values[0, 1].tolist() == [50032.0, 50032.1, 0.0]
    assert values[1, 1].tolist() == [70032.0, 70032.1, 0.0]
    assert tags.tolist() == [[-1, 9, -1, -1], [-1, 9, -1, -1]]
    fill_rows(values, tags, fills, 1, 9, 3, 2)  # present: no draw
    assert len(sampler.calls) == 2
    tags[1, 1] = 4  # the row taken by another key: only that table is refilled
    values[1, 1] = -1.0
    fill_rows(values, tags, fills, 1, 9, 3, 2)
    assert sampler.calls[2:] == [(7, 3, 2)]
    assert values[1, 1].tolist() == [70032.0, 70032.1, -1.0]


def test_draw_tables_map_sources_to_tables_and_fill_by_index() -> None:
    sampler = Counting()
    lat = DrawCache(2, sampler)
    step = DrawCache(2, sampler)
    const = DrawCache(2, sampler, constant=0.25)
    tables = DrawTables([(SVC_PUB, K_TRIGGER, lat), (STEP, 0, step), (SVC_PUB, K_STATE, const)],
                        history=3, subjects=2)
    assert (tables.tables, tables.draw_map[SVC_PUB, K_TRIGGER], tables.draw_map[STEP, 0]) == (
        2, 0, 1)
    assert tables.draw_map[SVC_PUB, K_STATE] == -1 and tables.draw_const[SVC_PUB] == 0.25
    tables.fill(K_TRIGGER, 4)  # row 4 % 3 = 1 of the trigger's table
    tables.fill(0, 2)  # the compute stream: sampled with STEP_DRAW
    assert sampler.calls == [(K_TRIGGER, 4, 0), (STEP_DRAW, 2, 0)]
    assert tables.values[0, 1].tolist() == [K_TRIGGER * 1e4 + 40.0, K_TRIGGER * 1e4 + 40.1]
    assert tables.tags.tolist() == [[-1, 4, -1], [-1, -1, 2]]
    tables.fill(K_TRIGGER, 4)
    assert len(sampler.calls) == 2
