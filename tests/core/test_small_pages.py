"""numpy's huge-page hint is switched off by a run's truth, unless the user set numpy's switch."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from sigma_des.core import pages
from sigma_des.events.truth import SwarmTruth
from sigma_des.factory import make_dynamics
from tests.conftest import tiny


@pytest.fixture
def hint() -> Iterator[None]:
    """The hint as it was before the test, restored after it."""
    hooks = pages._hooks()
    assert hooks is not None
    was = hooks[1]()
    yield
    hooks[0](was)


def test_a_truth_switches_the_hint_off(hint: None, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(pages.ENV, raising=False)
    pages._hooks()[0](True)  # type: ignore[index]
    assert pages.huge_page_hint()
    SwarmTruth(make_dynamics(tiny()), 3, 16, 10.0, checkpoints=True)
    assert not pages.huge_page_hint()
    assert pages.small_pages()  # idempotent


@pytest.mark.parametrize("value", ["1", "0"])
def test_numpys_own_switch_wins(hint: None, monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    monkeypatch.setenv(pages.ENV, value)
    pages._hooks()[0](value == "1")  # type: ignore[index]  # as numpy read it at import
    assert pages.small_pages() is (value == "0")
    assert pages.huge_page_hint() is (value == "1")
