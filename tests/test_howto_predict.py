"""docs/howto/predict.md: its runnable blocks run (```bash: each line in a temp dir,
exit 0; ```python: the block in a temp dir), those marked ``<!-- no-test: ... -->`` are
skipped and say why."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parents[1] / "docs" / "howto" / "predict.md"
FENCE = re.compile(r"(?P<mark><!-- no-test: (?P<why>[^>]*?) -->\n)?```(?P<lang>bash|python)\n"
                   r"(?P<body>.*?)```", re.S)


def _blocks() -> list[tuple[str, str, str | None]]:
    return [(m["lang"], m["body"], m["why"]) for m in FENCE.finditer(PAGE.read_text())]


def _env() -> dict[str, str]:
    root = str(PAGE.parents[2])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([root, env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    return env


def test_page_has_a_title_and_runnable_blocks() -> None:
    text = PAGE.read_text()
    assert text.startswith("# ")
    blocks = _blocks()
    assert any(why is None for _, _, why in blocks)
    assert all(why.strip() for _, _, why in blocks if why is not None)


@pytest.mark.parametrize("index", range(len(_blocks())))
def test_block_runs(index: int, tmp_path: Path) -> None:
    lang, body, why = _blocks()[index]
    if why is not None:
        pytest.skip(f"no-test: {why}")
    if lang == "python":
        p = subprocess.run([sys.executable, "-c", body], cwd=tmp_path, env=_env(),
                           capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, p.stderr
        return
    for line in (ln for ln in body.splitlines() if ln.strip() and not ln.startswith("#")):
        p = subprocess.run(["bash", "-c", line], cwd=tmp_path, env=_env(),
                           capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, f"{line}: {p.stderr}"
