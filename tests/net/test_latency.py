"""Latency distributions: exact draws, moments, validation and empirical files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sigma_des.core.rng import Stream
from sigma_des.errors import ConfigError
from sigma_des.net.latency import Dist, dist_from, load_samples

S = Stream(7, "latency")
IDS = np.arange(1000)


def test_constant() -> None:
    d = Dist(value=0.005)
    x = d.sample(S, IDS, 3)
    assert x.shape == (1000,)
    assert np.all(x == 0.005)
    assert d.is_constant and d.mean_value() == 0.005


def test_uniform_is_affine_in_the_stream() -> None:
    d = Dist(dist="uniform", low=0.002, high=0.006)
    expected = 0.002 + 0.004 * S.uniform(IDS, 3)
    np.testing.assert_array_equal(d.sample(S, IDS, 3), expected)
    assert d.mean_value() == pytest.approx(0.004, rel=1e-15)
    assert not d.is_constant
    assert Dist(dist="uniform", low=0.1, high=0.1).is_constant


def test_normal_truncated_at_zero() -> None:
    d = Dist(dist="normal", mean=0.0, std=1.0)
    x = d.sample(S, np.arange(200_000))
    np.testing.assert_array_equal(x[:1000], S.truncated_normal(0.0, 1.0, 0.0, IDS))
    assert x.min() >= 0.0
    # Half-normal mean sqrt(2/pi); sample SE ~ 0.6/sqrt(2e5) = 1.3e-3
    assert d.mean_value() == pytest.approx(math.sqrt(2.0 / math.pi), rel=1e-12)
    assert abs(x.mean() - d.mean_value()) < 7e-3


def test_normal_far_from_zero_keeps_its_mean() -> None:
    d = Dist(dist="normal", mean=0.03, std=0.001)
    assert d.mean_value() == pytest.approx(0.03, rel=1e-12)


def test_lognormal_moments_are_of_the_variable() -> None:
    d = Dist(dist="lognormal", mean=0.03, std=0.01)
    sigma2 = math.log(10.0 / 9.0)
    mu = math.log(0.03) - sigma2 / 2
    x = d.sample(S, np.arange(200_000), 1)
    np.testing.assert_allclose(x[:1000], np.exp(mu + math.sqrt(sigma2) * S.normal(IDS, 1)))
    # SE of the mean: 0.01 / sqrt(2e5) = 2.2e-5
    assert abs(x.mean() - 0.03) < 1.2e-4
    assert abs(x.std() - 0.01) < 3e-4
    assert d.mean_value() == 0.03
    assert Dist(dist="lognormal", mean=0.02).is_constant
    assert np.all(Dist(dist="lognormal", mean=0.02).sample(S, IDS) == 0.02)


def test_exponential() -> None:
    d = Dist(dist="exponential", mean=0.004)
    np.testing.assert_array_equal(d.sample(S, IDS), 0.004 * S.exponential(IDS))
    assert d.mean_value() == 0.004


def _write(tmp_path: Path, name: str, text: str) -> str:
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_empirical_csv_with_header(tmp_path: Path) -> None:
    path = _write(tmp_path, "d.csv", "delay_s,host\n0.001,a\n\n0.002,b\n0.004,c\n")
    d = Dist(dist="empirical", file=path)
    u = S.uniform(IDS, 5)
    expected = np.array([0.001, 0.002, 0.004])[np.floor(u * 3).astype(int)]
    np.testing.assert_array_equal(d.sample(S, IDS, 5), expected)
    assert d.mean_value() == pytest.approx(0.007 / 3, rel=1e-15)
    assert not d.is_constant
    assert load_samples(path) is load_samples(path)  # cached


def test_empirical_one_per_line(tmp_path: Path) -> None:
    path = _write(tmp_path, "d.txt", "# measured\n0.5\n0.5\n")
    d = Dist(dist="empirical", file=path)
    assert d.is_constant
    assert np.all(d.sample(S, IDS) == 0.5)


def test_empirical_file_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError) as e:
        Dist(dist="empirical", file=str(tmp_path / "nope.csv"))
    assert e.value.key == "file"
    with pytest.raises(ConfigError) as e:
        Dist(dist="empirical")
    assert e.value.key == "file"
    with pytest.raises(ConfigError) as e:
        Dist(dist="empirical", file=_write(tmp_path, "neg.txt", "0.1\n-0.2\n"))
    assert e.value.key == "file" and ">= 0" in e.value.reason
    with pytest.raises(ConfigError):
        Dist(dist="empirical", file=_write(tmp_path, "empty.txt", "x\n"))


@pytest.mark.parametrize(
    "d",
    [
        Dist(value=0.01),
        Dist(dist="uniform", low=0.0, high=1.0),
        Dist(dist="normal", mean=0.01, std=0.02),
        Dist(dist="lognormal", mean=0.01, std=0.02),
        Dist(dist="exponential", mean=0.01),
    ],
)
def test_scalar_call_matches_array_call(d: Dist) -> None:
    arr = d.sample(S, IDS, 9)
    for i in (0, 1, 17, 999):
        one = d.sample(S, i, 9)
        assert one.shape == (1,)
        assert one[0] == arr[i]
    grid = d.sample(S, IDS[:, None], np.arange(3))
    assert grid.shape == (1000, 3)
    np.testing.assert_array_equal(grid[:, 2], d.sample(S, IDS, 2))
    assert (arr >= 0).all()


@pytest.mark.parametrize("d", [Dist(dist="normal", mean=0.2, std=0.04),
                               Dist(dist="normal", mean=0.01, std=0.02),
                               Dist(dist="lognormal", mean=0.0008, std=0.0002)])
def test_quantile_is_the_textbook_formula_bit_for_bit(d: Dist) -> None:
    """The quantile computes in place, with the truncation mass kept per distribution:
    the bits of ``mean + std ndtri(a + u (1 - a))`` (at least 0) and of
    ``exp(mu + sigma ndtri(u))``, the written-out formulas."""
    from scipy.special import ndtr, ndtri

    u = S.uniform(IDS[:, None], np.arange(4))
    if d.dist == "normal":
        a = float(ndtr((0.0 - d.mean) / d.std))
        want = np.maximum(d.mean + d.std * ndtri(a + u * (1.0 - a)), 0.0)
    else:
        s2 = math.log1p((d.std / d.mean) ** 2)
        want = np.exp((math.log(d.mean) - 0.5 * s2) + math.sqrt(s2) * ndtri(u))
    for _ in range(2):  # the kept mass serves again
        got = d.quantile(u)
        assert got.shape == u.shape and got.tobytes() == want.tobytes()
    assert (u == S.uniform(IDS[:, None], np.arange(4))).all()  # u is not written
    assert d.quantile(0.5).shape == (1,)


def test_validation_names_the_field() -> None:
    with pytest.raises(ConfigError) as e:
        Dist(value=-1)
    assert e.value.key == "value" and ">= 0" in e.value.reason
    for field in ("low", "high", "mean", "std"):
        with pytest.raises(ConfigError) as e:
            Dist(dist="uniform", **{field: -0.5})
        assert e.value.key == field
    with pytest.raises(ConfigError) as e:
        Dist(dist="uniform", low=2.0, high=1.0)
    assert e.value.key == "low"
    with pytest.raises(ConfigError) as e:
        Dist(dist="gamma")
    assert e.value.key == "dist" and "lognormal" in e.value.reason
    with pytest.raises(ConfigError) as e:
        Dist(dist="lognormal", mean=0.0, std=1.0)
    assert e.value.key == "mean"
    with pytest.raises(ConfigError):
        Dist(value=float("nan"))
    with pytest.raises(ConfigError):
        Dist(value=True)  # type: ignore[arg-type]


def test_ints_are_accepted_as_floats() -> None:
    d = Dist(dist="uniform", low=1, high=2)
    assert isinstance(d.low, float) and d.low == 1.0


def test_dist_from() -> None:
    assert dist_from(0.005) == Dist(dist="constant", value=0.005)
    assert dist_from(2) == Dist(value=2.0)
    d = Dist(dist="exponential", mean=1.0)
    assert dist_from(d) is d
    assert dist_from({"dist": "uniform", "low": 0, "high": 1}) == Dist("uniform", low=0, high=1)
    with pytest.raises(ConfigError) as e:
        dist_from({"dist": "uniform", "lo": 0})
    assert e.value.key == "lo"
    with pytest.raises(ConfigError) as e:
        dist_from({"value": -3})
    assert e.value.key == "value"
    with pytest.raises(ConfigError):
        dist_from("5ms")
    with pytest.raises(ConfigError):
        dist_from(True)
