"""The study's episodes (BiDES at 200 ms with 10 % loss, ``none``, perfect information)
are bit for bit the same whichever way the compiled core draws its frame draws: every
table's uniforms in one compiled call (``FrameDraws``' merged path) or one sampler call
per table, over several episodes and restarts."""

from __future__ import annotations

import pytest

from sigma_des.events.fast import frame_draws as FD
from tests.env.test_restart_recycling import CASES, _play


def _per_table(monkeypatch: pytest.MonkeyPatch) -> None:
    """Frame draws one sampler call per table (no merged call)."""
    monkeypatch.setattr(FD, "_merged", lambda sources: None)


@pytest.mark.parametrize("kind", sorted(CASES))
def test_merged_frame_draws_play_the_episodes_of_per_table_draws(
        monkeypatch: pytest.MonkeyPatch, kind: str) -> None:
    calls = []
    merged = FD._merged

    def counted(sources):  # type: ignore[no-untyped-def]
        got = merged(sources)
        calls.append(got is not None)
        return got

    with monkeypatch.context() as m:
        m.setattr(FD, "_merged", counted)
        fast = _play(kind, [0, 1, 2])
    assert calls and all(calls)  # every core drew its frames by the merged call
    with monkeypatch.context() as m:
        _per_table(m)
        ref = _play(kind, [0, 1, 2])
    assert fast == ref
