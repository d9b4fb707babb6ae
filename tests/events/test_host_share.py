"""Host-correlated step times (``compute.host_share``, a Gaussian copula in ``step_draws``).

ρ = 0 must be today's draws bit for bit (and leave the scenario's TOML and hash alone);
ρ > 0 must correlate the normal scores of two nodes of one host by ρ, leave nodes of
different hosts independent and keep every draw's ``step_time`` distribution; both
engines read the same draws, so their results stay identical.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats
from scipy.special import ndtri

from sigma_des.config import config_hash, load, to_toml
from sigma_des.core.rng import RandomStreams
from sigma_des.errors import ConfigError
from sigma_des.events.jobs import ROLLBACK_DRAW, STEP_DRAW, step_draws
from sigma_des.events.spec import ComputeSpec
from sigma_des.net.latency import Dist
from tests.conftest import tiny
from tests.events.test_cohort import run_both

STEP = Dist(dist="lognormal", mean=0.003, std=0.002)
#: 6 nodes on 3 hosts: nodes 0, 1 on host 0, 2, 3 on host 1, 4, 5 on host 2.
HOST_OF = (0, 0, 1, 1, 2, 2)
FRAMES = 4000
#: ``STEP``'s lognormal as SciPy has it (sigma² = ln(1 + std²/mean²), mu = ln(mean) − sigma²/2).
_SIGMA = math.sqrt(math.log1p((STEP.std / STEP.mean) ** 2))
STEP_CDF = stats.lognorm(s=_SIGMA, scale=STEP.mean * math.exp(-0.5 * _SIGMA**2)).cdf


def _table(rho: float, seed: int = 7, kind: int = STEP_DRAW) -> np.ndarray:
    """Draws of every node for frames 0..FRAMES-1, shape (FRAMES, nodes)."""
    draws = step_draws(ComputeSpec(step_time=STEP, host_share=rho), RandomStreams(seed), HOST_OF)
    return np.stack([draws.vector(kind, f, 0) for f in range(FRAMES)])


def _fisher_halfwidth(n: int, z: float = 4.0) -> float:
    """Half-width of a Pearson correlation's ``z``-sigma band near ρ (Fisher's z: the
    standard error of atanh(r) is 1/sqrt(n-3))."""
    return z / math.sqrt(n - 3)


def test_rho_zero_is_todays_draws_bit_for_bit() -> None:
    """ρ = 0: every draw is ``step_time`` sampled from stream ``compute`` at its key."""
    streams = RandomStreams(3)
    d = step_draws(ComputeSpec(step_time=STEP), streams, HOST_OF)
    s = streams.stream("compute")
    nodes = np.arange(len(HOST_OF))
    for kind, idx, att in ((STEP_DRAW, 5, 0), (STEP_DRAW, 9999, 0), (ROLLBACK_DRAW, 40, 3)):
        want = STEP.sample(s, kind, nodes, idx, att)
        np.testing.assert_array_equal(d.vector(kind, idx, att), want)
        assert d.get(kind, 4, idx, att) == STEP.sample(s, kind, 4, idx, att)[0]


def test_host_share_zero_is_not_written_and_keeps_the_hash(tmp_path: Path) -> None:
    sc = tiny()
    assert "host_share" not in to_toml(sc)
    assert config_hash(tiny(compute__host_share=0.0)) == config_hash(sc)
    on = tiny(compute__host_share=0.5)
    assert "host_share = 0.5" in to_toml(on)
    assert config_hash(on) != config_hash(sc)
    (tmp_path / "on.toml").write_text(to_toml(on))
    assert load(tmp_path / "on.toml").compute.host_share == 0.5


@pytest.mark.parametrize("bad", [-0.1, 1.0, 1.5, math.nan, math.inf, True])
def test_host_share_out_of_range_is_refused_naming_the_key(bad: float) -> None:
    with pytest.raises(ConfigError, match=r"host_share.*\[0, 1\)"):
        ComputeSpec(host_share=bad)


def test_scores_correlate_by_rho_within_a_host_and_not_across() -> None:
    """ρ = 0.8: the normal scores Φ⁻¹(F(x)) of two nodes of one host over 4000 frames
    correlate 0.8 within a 4-sigma Fisher band (±0.023 at ρ = 0.8: the band of atanh(r),
    ±4/sqrt(n-3), mapped back through tanh), nodes of different hosts 0 ± 0.063."""
    z = ndtri(STEP_CDF(_table(0.8)))
    h = _fisher_halfwidth(FRAMES)
    lo, hi = math.tanh(math.atanh(0.8) - h), math.tanh(math.atanh(0.8) + h)
    for a, b in ((0, 1), (2, 3), (4, 5)):
        r = float(np.corrcoef(z[:, a], z[:, b])[0, 1])
        assert lo < r < hi, (a, b, r)
    for a, b in ((0, 2), (1, 5), (3, 4)):
        r = float(np.corrcoef(z[:, a], z[:, b])[0, 1])
        assert abs(r) < math.tanh(h), (a, b, r)
    # ρ = 0 gives no within-host correlation
    z0 = ndtri(STEP_CDF(_table(0.0)))
    assert abs(float(np.corrcoef(z0[:, 0], z0[:, 1])[0, 1])) < math.tanh(h)


def test_marginal_is_the_step_time_distribution() -> None:
    """Each node's 4000 draws at ρ = 0.8 pass a KS test against ``step_time``'s lognormal
    (p > 0.001), as the draws of ρ = 0 do; the rollback draws too."""
    for kind in (STEP_DRAW, ROLLBACK_DRAW):
        x = _table(0.8, kind=kind)
        for node in (0, 3, 5):
            assert stats.kstest(x[:, node], STEP_CDF).pvalue > 0.001, (kind, node)
    # and the mean and std the user configured, to sampling error (4 sigma)
    x = _table(0.8)[:, 1]
    assert abs(x.mean() - STEP.mean) < 4 * STEP.std / math.sqrt(FRAMES)


@pytest.mark.parametrize("dist", [
    Dist(dist="constant", value=0.002),
    Dist(dist="uniform", low=0.001, high=0.003),
    Dist(dist="normal", mean=0.002, std=0.001),
    Dist(dist="exponential", mean=0.002),
])
def test_other_distributions_keep_their_marginal(dist: Dist) -> None:
    d = step_draws(ComputeSpec(step_time=dist, host_share=0.6), RandomStreams(1), HOST_OF)
    x = np.concatenate([d.vector(STEP_DRAW, f, 0) for f in range(2000)])
    u = (np.arange(x.size) + 0.5) / x.size
    if dist.dist == "constant":
        assert d.constant == 0.002 and np.all(x == 0.002)
        return
    # KS distance to the distribution (its quantiles on a fine grid stand for its CDF);
    # 12 000 draws: the 0.001 critical value is 1.95/sqrt(12000) = 0.018
    assert stats.ks_2samp(x, dist.quantile(u)).statistic < 0.018


def test_scenario_with_host_share_identical_on_both_engines() -> None:
    """Both engines read the same draws: with ρ = 0.8 (lognormal steps, 2 hosts of one
    core) every metric of the cohort and the per-message engine agrees bit for bit, the
    cohort core running it (no fallback); and ρ changes the result."""
    step = {"dist": "lognormal", "mean": 0.003, "std": 0.002}
    base = tiny(hosts=2, cores_per_host=1, compute__step_time=step)
    sc = tiny(hosts=2, cores_per_host=1, compute__step_time=step, compute__host_share=0.8)
    for method in ("none", "lockstep", "bides"):
        ev, co = run_both(sc, method)
        assert co["engine"]["used"] == "cohort"
        ev0, _ = run_both(base, method)
        assert ev["metrics"]["aoi_mean"] != ev0["metrics"]["aoi_mean"]
