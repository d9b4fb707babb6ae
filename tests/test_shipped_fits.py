"""The fits shipped as package data: ``dynamics_params = "minisgs"`` names the fixed wing
fitted to JSBSim's minisgs glider; it loads, trims at the preset's cruise speed with its
propeller, and ``compare`` flies it. A path that exists always wins over a shipped name."""

from __future__ import annotations

from pathlib import Path

import pytest

from sigma_des.agents.fitted import (
    FITS_DIR,
    fitted_params,
    read_fitted,
    resolve_fitted,
    shipped_fits,
)
from sigma_des.cli import main
from sigma_des.config import load
from sigma_des.errors import ConfigError


def test_minisgs_is_shipped_and_resolves() -> None:
    assert "minisgs" in shipped_fits()
    assert resolve_fitted("minisgs") == FITS_DIR / "minisgs.toml"
    assert resolve_fitted("minisgs.toml") == FITS_DIR / "minisgs.toml"
    assert resolve_fitted("no_such_fit") == Path("no_such_fit")
    kind, values = read_fitted("minisgs")
    assert kind == "fixedwing"
    # the glider's measured structure (JSBSim minisgs: 11.07 lb, 42.23 ft^2, 8 ft span)
    assert values["mass"] == pytest.approx(11.07 * 0.45359237, rel=1e-4)
    assert values["s"] == pytest.approx(42.23 * 0.3048 ** 2)
    assert values["b"] == pytest.approx(8 * 0.3048)


def test_an_existing_file_wins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    Path("minisgs").write_text('dynamics = "quadrotor"\n[params]\nixx = 0.02\n')
    assert read_fitted("minisgs") == ("quadrotor", {"ixx": 0.02})
    with pytest.raises(ConfigError):
        fitted_params("minisgs", "fixedwing")


def test_the_minisgs_fit_trims_and_flies_in_compare(tmp_path: Path) -> None:
    from sigma_des.agents.aircraft import GeneralAircraft

    p = fitted_params("minisgs", "fixedwing")
    trim = GeneralAircraft(p).trim
    assert 0 < trim["omega"] < p.omega_max and abs(trim["delta_e"]) < p.delta_max
    sc = load(None, ['dynamics="fixedwing"', 'dynamics_params="minisgs"'])
    assert sc.dynamics_params == "minisgs"
    assert main(["compare", "--set", 'dynamics="fixedwing"', "--set",
                 'dynamics_params="minisgs"', "--set", "nodes=2", "--set", "duration=1.0",
                 "--methods", "none", "--out", str(tmp_path / "o"), "--no-plots"]) == 0
