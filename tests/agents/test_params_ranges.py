"""Aircraft parameters outside any aircraft's range are refused naming key and range, and
a ``dynamics_params`` file that is not text is one line (issue 26)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sigma_des.agents.params import PARAM_RANGES, AeroCoeffs, check_range
from sigma_des.agents.presets import PRESETS, preset
from sigma_des.cli import main
from sigma_des.errors import ConfigError

RUN = ["compare", "--set", "nodes=2", "--set", "duration=0.5", "--set", "warmup=0.1",
       "--set", "dynamics=quadrotor", "--methods", "none", "--no-progress"]


def test_presets_are_inside_the_ranges() -> None:
    for name in PRESETS:
        p = preset(name)
        for f in dataclasses.fields(p):
            v = getattr(p, f.name)
            if isinstance(v, float):
                assert check_range(f.name, v) is None, (name, f.name)


@pytest.mark.parametrize(("key", "value", "why"), [
    ("ixx", 1e300, "must be in (0, 100000] kg m^2, got 1e+300"),
    ("mass", 1e9, "must be in (0, 10000] kg, got 1000000000.0"),
    ("omega_max", 1e7, "must be in (0, 100000] rad/s, got 10000000.0"),
    ("v_cruise", -1.0, "must be in [0, 400] m/s, got -1.0"),
    ("altitude", 1e6, "must be in [-1000, 100000] m, got 1000000.0"),
])
def test_absurd_top_level_values(key: str, value: float, why: str) -> None:
    with pytest.raises(ConfigError) as ei:
        dataclasses.replace(preset("quadrotor"), **{key: value})
    assert ei.value.key == f"quadrotor.{key}" and ei.value.reason == why


def test_absurd_aero_coefficient_and_gain() -> None:
    q = preset("quadrotor")
    with pytest.raises(ConfigError) as ei:
        dataclasses.replace(q, aero=AeroCoeffs(s=0.016, cd_0=1e6))
    assert ei.value.key == "quadrotor.aero.cd_0"
    assert ei.value.reason == "must be in [-1000, 1000], got 1000000.0"
    with pytest.raises(ConfigError) as ei:
        dataclasses.replace(q, gains={**q.gains, "k_vel": 1e9})
    assert ei.value.key == "quadrotor.gains.k_vel"
    assert set(PARAM_RANGES) >= {"aero.*", "gains.*"}


def test_dynamics_params_absurd_value_exits_2(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "big.toml"
    f.write_text('dynamics = "quadrotor"\n[params]\nixx = 1e300\n')
    assert main([*RUN, "--set", f"dynamics_params={f}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "dynamics_params" in err
    assert "quadrotor.ixx: must be in (0, 100000] kg m^2, got 1e+300" in err


@settings(max_examples=20, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=200).map(lambda b: b + b"\xff"))
def test_dynamics_params_binary_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             data: bytes) -> None:
    f = tmp_path / "p.toml"
    f.write_bytes(data)
    assert main(["config", "--set", "dynamics=quadrotor", "--set", f"dynamics_params={f}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"sigma-des: error: dynamics_params: {f}: not a UTF-8 text fitted")
    assert err.count("\n") == 1 and "Traceback" not in err


def test_tune_bounds_outside_the_range_are_refused() -> None:
    from sigma_des.tuning.spec import TuneSpec, bounds

    spec = TuneSpec(params=("ixx",), lower=(0.01,), upper=(1e300,))
    with pytest.raises(ConfigError) as ei:
        bounds(spec, preset("quadrotor"), "quadrotor")
    assert ei.value.key == "tune.upper[0]"
    assert ei.value.reason == "upper bound of 'ixx' must be in (0, 100000] kg m^2, got 1e+300"
    with pytest.raises(ConfigError) as ei:
        bounds(TuneSpec(params=("cd_0",), scale_high=1e5), preset("quadrotor"), "quadrotor")
    assert ei.value.key == "tune.scale_high"
