"""README examples are executed, so they cannot rot."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from sigma_des.cli import main

README = Path(__file__).resolve().parents[1] / "README.md"


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", README.read_text(), flags=re.S)


def test_python_examples_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocks = _blocks("python")
    assert blocks, "README has no python example"
    monkeypatch.chdir(tmp_path)
    for code in blocks:
        exec(compile(code, "README.md", "exec"), {})
    assert (tmp_path / "out" / "example" / "results.csv").exists()


def test_readme_commands_are_the_ci_commands() -> None:
    text = README.read_text()
    ci = (README.parent / ".ci" / "run").read_text()
    test_cmd = ".venv/bin/python -m pytest -n 2"
    assert test_cmd in text and test_cmd in ci
    assert "pip install -e '.[dev]'" in text and "pip install -q -e '.[dev]'" in ci


def test_readme_scenario_file_loads_and_cli_config_runs(capsys: pytest.CaptureFixture[str],
                                                        monkeypatch: pytest.MonkeyPatch,
                                                        tmp_path: Path) -> None:
    """The README's scenarios load: paths from the checkout, shipped names from anywhere."""
    words = [ln.split()[2] for b in _blocks("bash") for ln in b.splitlines()
             if ln.startswith("sigma-des compare ")]
    args = [w for w in words if re.fullmatch(r"\w[\w./]*", w)]  # not options, [SCENARIO], ...
    assert {a.endswith(".toml") for a in args} == {True, False}, "README shows no name or path"
    for arg in args:
        monkeypatch.chdir(README.parent if "/" in arg else tmp_path)
        assert main(["config", arg]) == 0
        assert "\nnodes = 10\n" in capsys.readouterr().out


def test_readme_error_message_is_real(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["compare", "--set", "net.host_link.loss.p=1.0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err in README.read_text()
