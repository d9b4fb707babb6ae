"""A fitted ``dynamics_params`` file without parameters is refused naming ``[params]``
(it used to fly the preset, silently)."""

from __future__ import annotations

from pathlib import Path

import pytest

from sigma_des.agents.fitted import read_fitted
from sigma_des.cli import main
from sigma_des.errors import ConfigError


@pytest.mark.parametrize(("body", "why"), [
    ('dynamics = "quadrotor"\n', "params: missing: a fitted file holds a [params] table"),
    ('dynamics = "quadrotor"\n[params]\n', "params: is empty: a fitted file holds at least one"),
    ('dynamics = "quadrotor"\n[provenance]\nsource = "x"\n', "params: missing"),
])
def test_a_file_without_fitted_values_is_refused(
        body: str, why: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "fitted.toml"
    f.write_text(body)
    with pytest.raises(ConfigError) as ei:
        read_fitted(f)
    assert f"{ei.value}".startswith(f"{f}: {why}")
    assert main(["config", "--set", "dynamics=quadrotor", "--set", f"dynamics_params={f}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"sigma-des: error: dynamics_params: {f}: {why}"), err
    assert err.count("\n") == 1


def test_a_file_with_a_value_is_read(tmp_path: Path) -> None:
    f = tmp_path / "fitted.toml"
    f.write_text('dynamics = "quadrotor"\n[params]\nixx = 0.02\n')
    assert read_fitted(f) == ("quadrotor", {"ixx": 0.02})
