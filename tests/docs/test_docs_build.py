"""The documentation builds with warnings as errors, and the generated pages are in it."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.early
def test_docs_build_with_warnings_as_errors(tmp_path: Path) -> None:
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    out = tmp_path / "html"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), str(ROOT / "lab"), os.environ.get("PYTHONPATH", "")])}
    r = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(ROOT / "docs"), str(out)],
        capture_output=True, text=True, env=env, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-5000:]
    page = (out / "reference" / "generated" / "keys.html").read_text()
    for key in ("net.host_link.loss.p", "deployment.host_runq", "faults[].extra_loss",
                "bides.f_trig_min"):
        assert key in page, key
    assert "[0, 1)" in page and "(0, 10000]" in page  # loss p; the rates
    cli = (out / "reference" / "cli.html").read_text()
    for option in ("--jobs", "--bundle", "--grid", "--rate"):
        assert option in cli, option
    api = (out / "reference" / "api.html").read_text()
    assert "run_method" in api and "ConfigError" in api
    outputs = (out / "reference" / "generated" / "outputs.html").read_text()
    assert "aoi_peak_mean" in outputs and "foxglove.PosesInFrame" in outputs
    data = ROOT / "docs" / "results" / "data"
    for name in ("validation", "performance", "learning"):
        html = (out / "results" / f"{name}.html").read_text()
        for run in data.glob("*/run.json"):
            facts = json.loads(run.read_text())
            if facts["page"] == name:  # every filed study is on its page, with its date
                assert facts["title"] in html and facts["date"] in html, run
    glossary = (out / "glossary.html").read_text()
    assert 'id="term-BiDES"' in glossary
    assert "0.1.0" in (out / "changelog.html").read_text()
    index = (out / "searchindex.js").read_text()
    terms = json.loads(re.search(r"Search\.setIndex\((.*)\)\s*$", index, re.S).group(1))
    assert "bide" in terms["terms"] or "bides" in terms["terms"]
