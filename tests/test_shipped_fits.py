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


def test_gains_in_fitted_files(tmp_path: Path) -> None:
    from sigma_des.agents.fitted import get_value, with_values
    from sigma_des.agents.presets import preset

    base = preset("fixedwing")
    p = with_values(base, {"gains.k_chi": 0.6, "cm_q": -20.0})
    assert p.gains["k_chi"] == 0.6 and p.aero.cm_q == -20.0
    assert {k: v for k, v in p.gains.items() if k != "k_chi"} == {
        k: v for k, v in base.gains.items() if k != "k_chi"}
    assert get_value(p, "gains.k_chi") == 0.6
    f = tmp_path / "g.toml"
    f.write_text('dynamics = "fixedwing"\n[params]\n"gains.k_r" = 0.5\n')
    assert fitted_params(f, "fixedwing").gains["k_r"] == 0.5
    f.write_text('dynamics = "fixedwing"\n[params]\n"gains.nope" = 0.5\n')
    with pytest.raises(ConfigError) as ei:
        fitted_params(f, "fixedwing")
    assert ei.value.key.endswith("params") and "gains.nope" in ei.value.reason
    # the shipped fit carries the gains retuned for its airframe
    assert fitted_params("minisgs", "fixedwing").gains["k_chi"] == 0.6


def test_tune_writes_the_init_files_values_with_the_genes() -> None:
    """fitted.toml alone rebuilds the tuned aircraft: an --init file's departures from the
    preset (structure, gains) are written with the fitted genes."""
    from sigma_des.agents.fitted import with_values
    from sigma_des.agents.presets import preset
    from sigma_des.tuning.pipeline import _file_values

    start = with_values(preset("fixedwing"), {"mass": 4.0, "gains.k_chi": 0.5, "cm_q": -30.0})
    assert _file_values(start, "fixedwing", {"cm_q": -10.0}) == {
        "mass": 4.0, "gains.k_chi": 0.5, "cm_q": -10.0}
    assert _file_values(preset("fixedwing"), "fixedwing", {"cm_q": -10.0}) == {"cm_q": -10.0}
