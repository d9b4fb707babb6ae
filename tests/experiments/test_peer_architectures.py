"""``experiments/peer_architectures.py --quick``, its report section and its scenario files."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from sigma_des import load

ROOT = Path(__file__).resolve().parents[2]
EXP = ROOT / "experiments"
sys.path.insert(0, str(EXP))

import peer_architectures as study  # noqa: E402
import report_peer  # noqa: E402

from sigma_des.config import with_overrides  # noqa: E402


@pytest.fixture(scope="module")
def summary(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    out = tmp_path_factory.mktemp("outputs")
    subprocess.run([sys.executable, str(EXP / "peer_architectures.py"), "--quick", "--out",
                    str(out / study.NAME)], check=True, timeout=300, capture_output=True)
    return out, json.loads((out / study.NAME / "summary.json").read_text())


def test_quick_run_writes_every_label_and_plot(summary: tuple[Path, dict[str, Any]]) -> None:
    out, s = summary
    table = s["extra"]["table"]
    assert set(table) == {spec.label for spec in study.LABELS}
    for rows in table.values():
        assert set(rows) == {str(n) for n in study.QUICK_NODES}
        for c in rows.values():
            assert c["aoi_mean"] >= c["latency_state_mean"]  # shown after it arrived
            assert c["rtf"] == pytest.approx(c["trigger_rate_hz"] / 100.0)
    assert set(s["plots"]) == {"aoi_vs_n.png", "rate_vs_n.png"}
    assert (out / study.NAME / "results.csv").stat().st_size > 0


def test_quick_run_orders_the_architectures(summary: tuple[Path, dict[str, Any]]) -> None:
    """Inequalities that hold by construction on identical draws."""
    table = summary[1]["extra"]["table"]
    for n in (str(x) for x in study.QUICK_NODES):
        # a frame of RPC includes a render of >= render_per_vehicle * N: slower than 100 Hz
        assert table["rpc"][n]["trigger_rate_hz"] < table["bides_mqtt"][n]["trigger_rate_hz"]
        # the executor scan only adds reader cost
        assert (table["lockstep_dds"][n]["latency_state_mean"]
                >= table["lockstep_dds_noscan"][n]["latency_state_mean"])


def test_report_section(summary: tuple[Path, dict[str, Any]], tmp_path: Path) -> None:
    text = report_peer.section(summary[0])
    assert text.startswith(f"## {report_peer.TITLE}")
    assert "| lockstep_dds | 16 |" in text and "quick mode" in text
    assert "Not run" in report_peer.section(tmp_path)


def test_unstable_definition() -> None:
    assert study.unstable({"trigger_rate_hz": 49.9, "stalls": 0}, 100.0)
    assert study.unstable({"trigger_rate_hz": 100.0, "stalls": 1}, 100.0)
    assert not study.unstable({"trigger_rate_hz": 50.0, "stalls": 0}, 100.0)


@pytest.mark.parametrize(("path", "label"), [("gazebo_lockstep_dds.toml", "lockstep_dds"),
                                             ("airsim_rpc.toml", "rpc")])
def test_scenario_files_match_the_study(path: str, label: str) -> None:
    sc = load(ROOT / "scenarios" / path)
    spec = next(s for s in study.LABELS if s.label == label)
    assert sc.methods == (spec.method,)
    # the study's overrides for this architecture change nothing in the scenario file
    assert with_overrides(sc, spec.overrides) == sc
    base = load(None, study.overrides(sc.nodes, quick=False))
    assert (base.f_trig, base.hosts, base.duration) == (sc.f_trig, sc.hosts, sc.duration)
