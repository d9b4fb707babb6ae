"""Smoke run of the physics benchmark script (structure only; timings are never asserted)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_physics_quick_prints_every_model() -> None:
    out = subprocess.run([sys.executable, str(ROOT / "experiments" / "bench_physics.py"),
                          "--quick"], capture_output=True, text=True, check=True,
                         cwd=ROOT, timeout=300).stdout
    rows = [ln.split() for ln in out.splitlines() if ln and ln.split()[0] in (
        "quadrotor", "fixedwing", "pointmass", "jsbsim:F450", "jsbsim:c172x")]
    models = {r[0] for r in rows}
    assert models == {"quadrotor", "fixedwing", "pointmass", "jsbsim:F450", "jsbsim:c172x"}
    # every vectorised model is timed for 1 000 and 10 000 aircraft
    for model in ("quadrotor", "fixedwing", "pointmass"):
        ns = {tok for r in rows if r[0] == model for tok in r[1:3] if tok.isdigit()}
        assert {"1000", "10000"} <= ns, model
    for r in rows:
        nums = [float(x) for x in r if x.replace(".", "", 1).isdigit()]
        assert nums and all(x > 0 for x in nums)
