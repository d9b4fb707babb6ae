"""Run the code blocks of a documentation page, as a reader would, in a fresh folder.

The convention every page of ``docs/tutorial/`` and ``docs/howto/`` is written to:

* fenced ```` ```python ```` blocks run in page order in one namespace per page;
* fenced ```` ```bash ```` blocks: every non-empty line that is not a comment runs with
  ``bash -c`` (a line ending in ``\\`` continues on the next), in page order, and must
  exit 0; the venv's ``bin`` folder is first on ``PATH``;
* both run with the current directory a fresh temporary folder, one per page;
* a fence whose immediately preceding line is ``<!-- no-test: REASON -->`` is not run
  (REASON must not be empty);
* a ```` ```toml ```` block whose immediately preceding line is ``<!-- file: NAME -->``
  is written to ``NAME`` in that folder before the blocks after it run;
* every other block (``text``, ``console``, ``toml`` without a file comment …) is
  shown, not run. Blocks inside a MyST directive (```` ```{note} ````) follow the same
  rules.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Block", "PageError", "blocks", "run_page"]

_FENCE = re.compile(r"^(?P<indent> {0,3})(?P<fence>`{3,}|~{3,})\s*(?P<info>[^`]*)$")
_NO_TEST = re.compile(r"^\s*<!--\s*no-test:(?P<reason>.*?)-->\s*$")
_FILE = re.compile(r"^\s*<!--\s*file:\s*(?P<name>\S+)\s*-->\s*$")
#: a bash line may run this long before the page fails (a hung command, not a timing test)
LINE_TIMEOUT_S = 900


class PageError(AssertionError):
    """A block of a page failed (or the page breaks the convention)."""


@dataclass(frozen=True)
class Block:
    """One fenced block.

    Attributes:
        lang: the info string's first word (``python``, ``bash``, ``{note}`` …).
        code: the block's text.
        line: its first line in the page (1-based, the fence's line).
        skip: the reason of a ``no-test`` comment before it (None: not skipped).
        file: the ``file`` comment's name before it (None: none).
    """

    lang: str
    code: str
    line: int
    skip: str | None = None
    file: str | None = None


def blocks(text: str, first_line: int = 1) -> list[Block]:
    """The fenced blocks of a Markdown text, in order (directive bodies searched too)."""
    lines = text.splitlines()
    out: list[Block] = []
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        fence, info = m.group("fence"), m.group("info").strip()
        end = i + 1
        close = re.compile(rf"^ {{0,3}}{re.escape(fence[0])}{{{len(fence)},}}\s*$")
        while end < len(lines) and not close.match(lines[end]):
            end += 1
        body = "\n".join(lines[i + 1:end])
        lang = info.split()[0] if info else ""
        prev = lines[i - 1] if i > 0 else ""
        if lang.startswith("{"):
            out += blocks(body, first_line + i + 1)
        else:
            skip = _NO_TEST.match(prev)
            file = _FILE.match(prev)
            out.append(Block(lang, body + "\n", first_line + i,
                             skip.group("reason").strip() if skip else None,
                             file.group("name") if file else None))
        i = end + 1
    return out


def _bash_lines(code: str) -> list[str]:
    """The commands of a bash block: non-empty, non-comment lines, ``\\`` joined."""
    out: list[str] = []
    cur = ""
    for raw in code.splitlines():
        line = raw.rstrip()
        if not cur and (not line.strip() or line.lstrip().startswith("#")):
            continue
        if line.endswith("\\"):
            cur += line[:-1] + " "
            continue
        out.append(cur + line)
        cur = ""
    if cur.strip():
        out.append(cur)
    return out


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    return env


def run_page(page: Path, workdir: Path) -> int:
    """Run ``page``'s blocks in ``workdir``; the number of blocks run.

    Raises:
        PageError: a block failed (its line named), or a ``no-test`` comment gives no
            reason.
    """
    name = page.name
    namespace: dict[str, object] = {"__name__": "__main__"}
    ran = 0
    old = Path.cwd()
    os.chdir(workdir)
    try:
        for b in blocks(page.read_text()):
            where = f"{name}:{b.line}"
            if b.skip is not None:
                if not b.skip:
                    raise PageError(f"{where}: `<!-- no-test: -->` needs a reason")
                continue
            if b.lang == "toml" and b.file:
                target = workdir / b.file
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_text(b.code)
            elif b.lang == "python":
                try:
                    exec(compile(b.code, where, "exec"), namespace)  # noqa: S102
                except Exception as e:
                    raise PageError(f"{where}: python block failed: {e!r}") from e
                ran += 1
            elif b.lang == "bash":
                for cmd in _bash_lines(b.code):
                    try:
                        r = subprocess.run(["bash", "-c", cmd], cwd=workdir, env=_env(),
                                           capture_output=True, text=True,
                                           timeout=LINE_TIMEOUT_S)
                    except subprocess.TimeoutExpired:
                        raise PageError(f"{where}: `{cmd}` still running after "
                                        f"{LINE_TIMEOUT_S} s") from None
                    if r.returncode != 0:
                        raise PageError(f"{where}: `{cmd}` exited {r.returncode}\n"
                                        f"{r.stdout[-1500:]}{r.stderr[-1500:]}")
                ran += 1
    finally:
        os.chdir(old)
    return ran
