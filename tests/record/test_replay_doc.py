"""The recorder example of docs/howto/record-foxglove.md runs (so it cannot rot)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[2] / "docs" / "howto" / "record-foxglove.md"


def test_recorder_doc_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocks = [b for b in re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
              if "Recorder(" in b]
    assert len(blocks) == 1
    monkeypatch.chdir(tmp_path)
    exec(compile(blocks[0], DOC.name, "exec"), {})
    assert (tmp_path / "mine.mcap").stat().st_size > 0
