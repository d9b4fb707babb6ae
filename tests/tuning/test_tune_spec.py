"""Tune settings and genes: validation naming the key, bounds, parameter application."""

from __future__ import annotations

import pytest

from sigma_des.agents.presets import preset
from sigma_des.errors import ConfigError
from sigma_des.tuning.spec import TuneSpec, bounds, get_value, with_values


def test_defaults_and_scale_bounds() -> None:
    p = preset("fixedwing")
    names, lo, hi = bounds(TuneSpec(), p, "fixedwing")
    assert names[0] == "cm_a"
    assert lo[0] == pytest.approx(-2.74 * 2) and hi[0] == pytest.approx(-2.74 * 0.5)
    i = names.index("cl_a")
    assert (lo[i], hi[i]) == pytest.approx((5.61 * 0.5, 5.61 * 2))


def test_with_values_sets_top_level_and_aero() -> None:
    p = with_values(preset("quadrotor"), {"ixx": 0.03, "cd_0": 0.7})
    assert get_value(p, "ixx") == 0.03 and p.aero.cd_0 == 0.7
    assert p.iyy == preset("quadrotor").iyy


@pytest.mark.parametrize(("kw", "key"), [
    ({"params": ("ixx", "bogus")}, "tune.params[1]"),
    ({"params": ("ixx", "iyy"), "lower": (0.03, 0.01), "upper": (0.02, 0.02)}, "tune.lower[0]"),
    ({"params": ("ixx",), "lower": (0.01,), "upper": ()}, "tune.upper"),
    ({"population": 1}, "tune.population"),
    ({"cxpb": 1.5}, "tune.cxpb"),
    ({"channels": ("phi", "alpha")}, "tune.channels[1]"),
    ({"elite": 32}, "tune.elite"),
    ({"band": -2}, "tune.band"),
])
def test_bad_settings_name_the_key(kw: dict[str, object], key: str) -> None:
    with pytest.raises(ConfigError) as e:
        TuneSpec(**kw)  # type: ignore[arg-type]
    assert e.value.key == key


def test_bounds_must_contain_start() -> None:
    spec = TuneSpec(params=("ixx",), lower=(0.03,), upper=(0.04,))
    with pytest.raises(ConfigError, match="do not contain its starting value"):
        bounds(spec, preset("quadrotor"), "quadrotor")
