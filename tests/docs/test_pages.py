"""Every code block of the tutorial and the how-to guides runs (docpages.py's convention).

Each page is one test, run in a fresh temporary folder; the harness itself is tested on
hand-made pages (a failing block fails, a skipped block needs a reason, a file comment
writes its file, text blocks are not run).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from docpages import PageError, blocks, run_page

DOCS = Path(__file__).resolve().parents[2] / "docs"
PAGES = sorted(p for folder in ("tutorial", "howto") for p in (DOCS / folder).glob("*.md"))


@pytest.mark.parametrize("page", PAGES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_page_runs(page: Path, tmp_path: Path) -> None:
    run_page(page, tmp_path)


GOOD = '''\
# A page

```python
x = 20 + 1
open("from_python.txt", "w").write(str(x))
```

Text in between.

<!-- file: scen/tiny.toml -->
```toml
nodes = 3
```

```bash
# a comment line is not run
test "$(cat from_python.txt)" = 21
test -f scen/tiny.toml && grep -q "nodes = 3" scen/tiny.toml
echo one \\
  two > joined.txt
```

```python
assert x == 21                          # one namespace per page
assert open("joined.txt").read() == "one two\\n"
```

```text
this is not run: exit 1
```

```toml
not = "written"
```

<!-- no-test: needs a broker -->
```bash
false
```

:::{note}
Inside a directive the same rules hold.
:::

````{tip}
```python
y = x * 2
```
````

```python
assert y == 42
```
'''


def _page(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "page.md"
    p.write_text(text)
    return p


def test_harness_runs_a_good_page(tmp_path: Path) -> None:
    work = tmp_path / "work"
    work.mkdir()
    assert run_page(_page(tmp_path, GOOD), work) == 5  # 4 python blocks + 1 bash block
    assert (work / "scen" / "tiny.toml").read_text() == "nodes = 3\n"
    assert not (work / "not").exists()


@pytest.mark.parametrize("bad", [
    "```python\nraise ValueError('boom')\n```\n",
    "```bash\ntrue\nfalse\ntrue\n```\n",
    "```bash\nexit 3\n```\n",
    "```python\nx = 1\n```\n\n```python\nassert x == 2\n```\n",
    "<!-- no-test: -->\n```bash\ntrue\n```\n",
    "<!-- no-test:    -->\n```python\npass\n```\n",
    "<!-- file: a.toml -->\n```toml\nk = 1\n```\n```bash\ntest -f b.toml\n```\n",
])
def test_harness_fails_a_bad_page(tmp_path: Path, bad: str) -> None:
    work = tmp_path / "work"
    work.mkdir()
    with pytest.raises(PageError):
        run_page(_page(tmp_path, bad), work)


def test_a_skip_comment_must_be_right_above_its_fence(tmp_path: Path) -> None:
    """A blank line between the comment and the fence: the block runs (and fails here)."""
    work = tmp_path / "work"
    work.mkdir()
    with pytest.raises(PageError, match="page.md:3"):
        run_page(_page(tmp_path, "<!-- no-test: reason -->\n\n```bash\nfalse\n```\n"), work)


def test_blocks_are_found_with_lines_and_comments() -> None:
    bs = blocks(GOOD)
    assert [b.lang for b in bs] == ["python", "toml", "bash", "python", "text", "toml",
                                    "bash", "python", "python"]
    assert bs[0].line == 3 and bs[1].file == "scen/tiny.toml" and bs[6].skip == "needs a broker"
    assert bs[5].file is None and bs[6].file is None
