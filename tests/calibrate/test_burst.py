"""The state hops scaled with the host's burst (``sigma_des.calibrate.burst``): the ratio
by hand, exactly which samples are scaled, and ``prepare`` applying it for a target."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sigma_des.calibrate.burst import (
    bundle_hop_factor,
    burst_ratio,
    calibration_nodes_per_host,
    floor_share,
    scale_state_hops,
    state_hop_factor,
)
from sigma_des.calibrate.target import prepare, state_hop_ratio
from sigma_des.config import Scenario, load
from sigma_des.net.latency import Dist, load_samples

UP = [0.0, 0.001, 0.0025]  # the states' hop samples (s)
DOWN = [0.0002, 0.0004]  # the triggers' and commands' hop samples (s)


def _cal(tmp: Path, nodes: int = 20, hosts: int = 2) -> Scenario:
    """A calibrated scenario as ``calibrate`` writes its links: the state hop file on
    the host link up and the server link down, the trigger hop file on the other two."""
    up, down = tmp / "hop_up.txt", tmp / "hop_down.txt"
    np.savetxt(up, UP)
    np.savetxt(down, DOWN)
    sc = load(None, [f"nodes={nodes}", f"hosts={hosts}"])
    u, d = Dist(dist="empirical", file=str(up)), Dist(dist="empirical", file=str(down))
    net = sc.net
    return replace(sc, net=replace(
        net, host_link=replace(net.host_link, latency=u, latency_down=d),
        server_link=replace(net.server_link, latency=d, latency_down=u)))


def _samples(dist: Dist | None) -> list[float]:
    assert dist is not None and dist.dist == "empirical"
    return list(load_samples(dist.file))


def test_the_ratio_is_the_mean_queue_ahead_in_a_burst_by_hand() -> None:
    """A burst of m arriving together keeps (m - 1) / 2 ahead on average: 10 nodes a
    host calibrated, 5 a host targeted -> 4/9; 15 -> 14/9; the same -> 1; one node a
    host targeted -> 0 (no other state ahead); calibrated at one a host -> never scaled."""
    assert burst_ratio(10.0, 5.0) == 4.0 / 9.0
    assert burst_ratio(10.0, 15.0) == 14.0 / 9.0
    assert burst_ratio(10.0, 10.0) == 1.0
    assert burst_ratio(10.0, 1.0) == 0.0
    assert burst_ratio(1.0, 30.0) == 1.0
    assert burst_ratio(0.5, 30.0) == 1.0


def test_the_calibration_burst_from_the_report_else_the_scenario(tmp_path: Path) -> None:
    cal = _cal(tmp_path, nodes=30, hosts=3)
    assert calibration_nodes_per_host(cal, {}) == 10.0
    assert calibration_nodes_per_host(cal, {"hop_nodes_per_host": 12.5}) == 12.5
    assert calibration_nodes_per_host(cal, {"hop_nodes_per_host": float("nan")}) == 10.0


def test_only_the_state_hops_are_scaled(tmp_path: Path) -> None:
    cal = _cal(tmp_path)
    out = scale_state_hops(cal, 0.5, tmp_path / "s")
    assert _samples(out.net.host_link.latency) == pytest.approx([0.0, 0.0005, 0.00125],
                                                                rel=1e-9, abs=0.0)
    assert _samples(out.net.server_link.latency_down) == _samples(out.net.host_link.latency)
    assert out.net.host_link.latency_down == cal.net.host_link.latency_down
    assert out.net.server_link.latency == cal.net.server_link.latency
    assert scale_state_hops(cal, 1.0, tmp_path / "s") is cal
    const = replace(cal, net=replace(cal.net, server_link=replace(
        cal.net.server_link, latency_down=Dist(dist="constant", value=0.001))))
    assert scale_state_hops(const, 0.5, tmp_path / "s") is const  # a user's latency


def test_an_unset_trigger_hop_keeps_the_unscaled_samples(tmp_path: Path) -> None:
    """Without its own ``latency_down`` the host link's down hop is its ``latency``:
    scaling the up hop must not scale the triggers' hop with it."""
    cal = _cal(tmp_path)
    cal = replace(cal, net=replace(cal.net, host_link=replace(cal.net.host_link,
                                                              latency_down=None)))
    out = scale_state_hops(cal, 2.0, tmp_path / "s")
    assert _samples(out.net.host_link.latency_down) == pytest.approx(UP)
    assert _samples(out.net.host_link.latency) == pytest.approx([0.0, 0.002, 0.005])


def test_prepare_scales_for_the_target_and_then_adds_the_latency(tmp_path: Path) -> None:
    """Calibrated at 20 nodes on 2 hosts (10 a host): 10 nodes on 2 hosts scale the state
    hops by 4/9; a +5 ms target adds 5 ms to the scaled samples, not scaled itself;
    the calibration's own size is left as calibrated."""
    cal = _cal(tmp_path)
    rep = {"delivery_service_per_client_s": 2e-5}
    small = prepare(cal, rep, ["nodes=10", "hosts=2"], samples_dir=tmp_path / "a")
    assert _samples(small.net.host_link.latency) == pytest.approx(
        [x * 4.0 / 9.0 for x in UP], rel=1e-8, abs=1e-15)
    assert _samples(small.net.host_link.latency_down) == pytest.approx(DOWN)
    shifted = prepare(cal, rep, ["nodes=10", "hosts=2"], add_latency_s=0.005,
                      samples_dir=tmp_path / "b")
    assert _samples(shifted.net.host_link.latency) == pytest.approx(
        [x * 4.0 / 9.0 + 0.005 for x in UP], rel=1e-8)
    same = prepare(cal, rep, ["nodes=40", "hosts=4"])
    assert same.net.host_link.latency == cal.net.host_link.latency
    big = prepare(cal, rep, ["nodes=30", "hosts=2"])  # no directory given: its own
    assert _samples(big.net.server_link.latency_down) == pytest.approx(
        [x * 14.0 / 9.0 for x in UP], rel=1e-8, abs=1e-15)


def test_a_bundled_target_keeps_the_calibrated_state_hops(tmp_path: Path) -> None:
    """With bundled messages a host's turn leaves in one PUBLISH or a few, not a burst
    of ``m``: the same 10-node target that scales per node keeps the samples."""
    cal = _cal(tmp_path)
    rep = {"delivery_service_per_client_s": 2e-5}
    out = prepare(cal, rep, ["nodes=10", "hosts=2"], bundle=True, samples_dir=tmp_path / "a")
    assert out.deployment.bundle
    assert out.net.host_link.latency == cal.net.host_link.latency
    assert out.net.server_link.latency_down == cal.net.server_link.latency_down


def test_the_bundled_factor_grows_with_the_servers_frame_by_hand() -> None:
    """``1 + (f - 1)(N - 1)/(N_b - 1)``: matched 1.9 on a bundled run of 10 nodes gives
    1.9 there, 1.4 at 5 (1 + 0.9 x 4/9), 2.8 at 19 (1 + 0.9 x 18/9), 1 at one node;
    a match below 1 shrinks, never below 0; no match (or a broken one) leaves the hops
    alone."""
    rep = {"bundle_hop_scale": 1.9, "bundle_hop_nodes": 10.0}
    assert bundle_hop_factor(rep, 10.0) == pytest.approx(1.9)
    assert bundle_hop_factor(rep, 5.0) == pytest.approx(1.4)
    assert bundle_hop_factor(rep, 19.0) == pytest.approx(2.8)
    assert bundle_hop_factor(rep, 1.0) == 1.0
    low = {"bundle_hop_scale": 0.5, "bundle_hop_nodes": 10.0}
    assert bundle_hop_factor(low, 5.5) == pytest.approx(0.75)
    assert bundle_hop_factor(low, 30.0) == 0.0
    assert bundle_hop_factor({}, 15.0) == 1.0
    assert bundle_hop_factor({"bundle_hop_scale": 1.9}, 15.0) == 1.0
    assert bundle_hop_factor({"bundle_hop_scale": float("nan"),
                              "bundle_hop_nodes": 20.0}, 15.0) == 1.0


def test_a_bundled_target_gets_the_matched_bundled_factor(tmp_path: Path) -> None:
    """A calibration that matched a bundled run of 10 nodes (1.9): a bundled target of 5
    nodes on 1 host has both state hops' samples times 1.4, the triggers' kept; on 5
    hosts (another nodes per host) the same; a per-node target keeps the per-node rule
    (10 nodes on 2 hosts: 5 a host against 10 calibrated, no floor reported: 4/9)."""
    cal = _cal(tmp_path)
    rep = {"delivery_service_per_client_s": 2e-5, "bundle_hop_scale": 1.9,
           "bundle_hop_nodes": 10.0}
    for hosts in (1, 5):
        out = prepare(cal, rep, ["nodes=5", f"hosts={hosts}"], bundle=True,
                      samples_dir=tmp_path / f"a{hosts}")
        assert _samples(out.net.host_link.latency) == pytest.approx([x * 1.4 for x in UP])
        assert _samples(out.net.server_link.latency_down) == pytest.approx(
            [x * 1.4 for x in UP])
        assert _samples(out.net.host_link.latency_down) == DOWN
        ratio, rule = state_hop_ratio(cal, rep, out)
        assert ratio == pytest.approx(1.4) and rule == "bundled; matched on a run of 10 nodes"
    node = prepare(cal, rep, ["nodes=10", "hosts=2"], samples_dir=tmp_path / "b")
    assert _samples(node.net.host_link.latency) == pytest.approx([x * 4 / 9 for x in UP])
    assert state_hop_ratio(cal, rep, node) == (pytest.approx(4 / 9),
                                               "per node; the host's burst at 5 nodes a host")
    plain = prepare(cal, {"delivery_service_per_client_s": 2e-5}, ["nodes=10", "hosts=2"],
                    bundle=True, samples_dir=tmp_path / "c")
    assert state_hop_ratio(cal, {}, plain) == (1.0, "bundled; no bundled calibration run: "
                                               "as calibrated")


def _states(method: str, lats: dict[tuple[int, int], list[float]]) -> pd.DataFrame:
    """States of ``method``: per (frame, host), latencies (ms) in publish order."""
    rows = []
    for (frame, host), ls in lats.items():
        for i, lat in enumerate(ls):
            t = frame * 0.01 + i * 1e-4
            rows.append({"method": method, "frame": frame, "host": host, "t_send": t,
                         "t_recv": t + lat * 1e-3})
    return pd.DataFrame(rows)


def test_floor_share_by_hand() -> None:
    """Lock-Step: host-first latencies 2 and 2 ms, all states mean (2+4+2+6)/4 = 3.5;
    none: all states mean (4+8)/2 = 6. Pooled = (3.5 + 6) / 2 = 4.75, so the share is
    2 / 4.75; without Lock-Step the host-first mean of every method: ((2+2)/2 + 4) / 2
    = 3 over (3.5 + 6) / 2."""
    ls = _states("lockstep", {(0, 0): [2.0, 4.0], (0, 1): [2.0, 6.0]})
    no = _states("none", {(0, 0): [4.0, 8.0]})
    both = pd.concat([ls, no.iloc[::-1]])  # row order does not matter, publish order does
    assert floor_share(both) == pytest.approx(2.0 / 4.75)
    hl = ls.assign(method="hlc")
    assert floor_share(pd.concat([hl, no])) == pytest.approx(3.0 / 4.75)
    assert np.isnan(floor_share(ls.iloc[:0]))


def test_state_hop_factor_keeps_the_floor() -> None:
    """Floor 0.4 kept, the rest scaled: 10 a host -> 5 a host gives 0.4 + 0.6 x 4/9;
    a floor outside [0, 1] or NaN counts as none."""
    assert state_hop_factor(10.0, 5.0, 0.4) == pytest.approx(0.4 + 0.6 * 4.0 / 9.0)
    assert state_hop_factor(10.0, 10.0, 0.4) == pytest.approx(1.0)
    assert state_hop_factor(10.0, 1.0, 0.4) == pytest.approx(0.4)
    assert state_hop_factor(10.0, 5.0, float("nan")) == 4.0 / 9.0
    assert state_hop_factor(10.0, 5.0, 1.5) == 4.0 / 9.0


def test_prepare_keeps_the_reported_floor(tmp_path: Path) -> None:
    cal = _cal(tmp_path)
    rep = {"delivery_service_per_client_s": 2e-5, "hop_floor_share": 0.25}
    out = prepare(cal, rep, ["nodes=10", "hosts=2"], samples_dir=tmp_path / "a")
    k = 0.25 + 0.75 * 4.0 / 9.0
    assert _samples(out.net.host_link.latency) == pytest.approx([x * k for x in UP],
                                                                rel=1e-8, abs=1e-15)


def test_without_bundle_a_bundled_calibration_predicts_one_publish_per_state(
        tmp_path: Path) -> None:
    """A calibration whose primary run was bundled: ``prepare`` without ``bundle`` gives
    per-node messages (what ``predict`` without ``--bundle`` promises); a ``--set`` of
    its own still wins; with ``bundle`` it is bundled."""
    cal = _cal(tmp_path)
    cal = replace(cal, deployment=replace(cal.deployment, clients="host", bundle=True))
    rep = {"delivery_service_per_client_s": 2e-5}
    assert not prepare(cal, rep, ["nodes=10"], samples_dir=tmp_path / "a").deployment.bundle
    assert prepare(cal, rep, ["nodes=10", "deployment.bundle=true"],
                   samples_dir=tmp_path / "b").deployment.bundle
    assert prepare(cal, rep, ["nodes=10"], bundle=True, samples_dir=tmp_path / "c"
                   ).deployment.bundle
