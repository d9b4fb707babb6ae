"""``sigma-des warmup``: its units cover every kernel a default comparison compiles."""

from __future__ import annotations

import subprocess
import sys

import pytest

from sigma_des.cli import main
from sigma_des.warmup.units import UNITS, run_unit, warm

_PROBE = """
import sys
from numba.core.dispatcher import Dispatcher
from sigma_des.api import compare
from sigma_des.warmup.units import UNITS, run_unit
from sigma_des.config import METHODS, load

def loaded():
    out = set()
    for name, mod in list(sys.modules.items()):
        if name.startswith("sigma_des"):
            for attr, obj in vars(mod).items():
                if isinstance(obj, Dispatcher):
                    out |= {(name, attr, str(sig)) for sig in obj.signatures}
    return out

for u in sys.argv[1:]:
    run_unit(u)
before = loaded()
sc = load(None, ["nodes=6", "hosts=2", "duration=0.4", "warmup=0.1"])
compare(sc, METHODS, progress=False)
print(len(before))
for item in sorted(loaded() - before):
    print(*item)
"""


def _missed(units: list[str]) -> tuple[int, list[str]]:
    r = subprocess.run([sys.executable, "-c", _PROBE, *units], capture_output=True, text=True,
                       timeout=600, check=True)
    lines = r.stdout.splitlines()
    return int(lines[0]), lines[1:]


def test_units_cover_a_default_comparison() -> None:
    """In a fresh process, after the units ran, a default-scenario comparison
    (quadrotors, formation commands, fidelity, every method) needs no kernel
    specialisation the warm-up did not load or compile; without the physics unit it
    does (so the check can fail)."""
    n, missed = _missed(list(UNITS))
    assert n > 10 and missed == []
    _n, without = _missed(["core"])
    assert any("step_kernel" in m for m in without)


def test_unknown_unit_and_bad_jobs_are_rejected(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ValueError, match="unknown warm-up unit 'gpu'"):
        run_unit("gpu")
    with pytest.raises(ValueError, match="allowed: core, physics"):
        warm(2, ["gpu"])
    assert main(["warmup", "--jobs", "0"]) == 2
    assert "--jobs: must be >= 1, got 0" in capsys.readouterr().err
