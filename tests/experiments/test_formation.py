"""``experiments/formation.py --quick``: outputs, columns, ideal-run convergence, DTW.

The script runs once as a subprocess into a temporary directory; the tests check
that its files exist with the required columns, that every follower converges to
its slot in the ideal run (finite convergence times), that the ideal run's DTW to
itself is exactly 0 while a networked run's is not, and that the table covers the
ideal run and every alignment method.
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "experiments" / "formation.py"
COLUMNS = {"study", "network", "seed", "config_hash", "version", "method", "metric", "value",
           "unit"}
LABELS = ("ideal", "none", "lockstep", "hlc", "bides")
PLOTS = ("trajectories.png", "convergence.png", "formation_error.png")
FOLLOWERS = (1, 2, 3, 4)


@pytest.fixture(scope="module")
def out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("formation")
    proc = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--out", str(d)],
                          cwd=ROOT, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "wrote" in proc.stdout
    return d


@pytest.fixture(scope="module")
def values(out: Path) -> dict[str, dict[str, float]]:
    with (out / "results.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert rows and set(rows[0]) == COLUMNS
    v: dict[str, dict[str, float]] = defaultdict(dict)
    for r in rows:
        assert r["study"] == "formation" and r["network"] == "lossy"
        assert r["config_hash"] and r["version"] and r["seed"] == "1"
        v[r["method"]][r["metric"]] = float(r["value"]) if r["value"] != "nan" else math.nan
    return v


def test_outputs_exist(out: Path) -> None:
    for name in ("results.csv", "summary.json", *PLOTS):
        assert (out / name).stat().st_size > 0, name
    s: dict[str, Any] = json.loads((out / "summary.json").read_text())
    assert s["quick"] is True and s["seeds"] == [1]
    assert set(s["methods"]) == set(LABELS)
    assert sorted(s["plots"]) == sorted(PLOTS)
    # The paper's formation parameters are the ones flown.
    fp = s["formation_parameters"]
    assert (fp["d"], fp["theta_deg"], fp["p_phi"], fp["p_psi"], fp["p_v"], fp["v_cru"]) == \
        (30.0, 45.0, 0.015, 0.4, 0.3, 20.0)
    assert s["scenario"]["dynamics"] == "fixedwing" and s["scenario"]["nodes"] == 5
    assert s["scenario"]["fidelity"]["log_rate"] == 30.0
    assert "ideal" in s["table"] and "bides" in s["table"]


def test_every_label_has_the_metrics(values: dict[str, dict[str, float]]) -> None:
    assert set(values) == set(LABELS)
    for lab in LABELS:
        for name in ("conv_h_s_mean", "conv_v_s_mean", "slot_h_mean_m", "formation_err_mean",
                     "dtw_r", "flight_s", *(f"dtw_r.node{k}" for k in range(5)),
                     *(f"conv_h_s.node{k}" for k in FOLLOWERS)):
            assert name in values[lab], (lab, name)
    for lab in LABELS[1:]:
        assert "aoi_mean" in values[lab] and "trigger_rate_hz" in values[lab]


def test_followers_converge_in_the_ideal_run(values: dict[str, dict[str, float]]) -> None:
    ideal = values["ideal"]
    for k in FOLLOWERS:
        for axis in ("h", "v"):
            t = ideal[f"conv_{axis}_s.node{k}"]
            assert math.isfinite(t) and 0.0 <= t < ideal["flight_s"], (axis, k, t)
    assert ideal["converged_h_frac"] == 1.0 and ideal["converged_v_frac"] == 1.0


def test_dtw_of_the_ideal_run_to_itself_is_zero(values: dict[str, dict[str, float]]) -> None:
    assert values["ideal"]["dtw_r"] == 0.0
    assert values["ideal"]["formation_err_mean"] == 0.0
    # A run over a lossy network does not fly exactly the ideal trajectories.
    assert values["none"]["dtw_r"] > 0.0
    for lab in LABELS:
        assert values[lab]["dtw_r"] >= 0.0


def test_dynamics_params_option_flies_a_fitted_wing() -> None:
    """``--dynamics-params minisgs``: the scenario carries the shipped fit (the run itself is
    the same code path as the default preset's)."""
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import formation
    finally:
        sys.path.remove(str(SCRIPT.parent))
    args = formation.parser().parse_args(["--dynamics-params", "minisgs"])
    sc = formation.scenario("default", 2.0, 1, args.dynamics_params)
    assert sc.dynamics == "fixedwing" and sc.dynamics_params == "minisgs"
    assert formation.scenario("default", 2.0, 1).dynamics_params == ""
