"""``calibrate RUN [RUN...]``: runs that cannot be combined refused naming the key, each
parameter from the runs that show it (hand-made fits), the background kept apart."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sigma_des import load
from sigma_des.calibrate.campaign import RunInfo, check_combinable, combine, under_load_warning
from sigma_des.cli import main
from sigma_des.errors import ConfigError
from sigma_des.net.latency import Dist
from tests.calibrate.test_calibrate_cpu import BACKGROUND_CPU, WINDOW, _cpu_run


def _info(name: str, bundle: bool, **scen: object) -> RunInfo:
    return RunInfo(name=name, scenario={"nodes": 4, "f_trig": 100.0, **scen}, bundle=bundle,
                   cores=2, background=0.1)


def test_runs_of_different_scenarios_are_refused_naming_the_key() -> None:
    check_combinable([_info("a", False), _info("b", True, nodes=60, hosts=3, seed=9)])
    with pytest.raises(ConfigError, match=r"^f_trig: differs between the runs a \(100.0\)"):
        check_combinable([_info("a", False), _info("b", False, f_trig=50.0)])
    with pytest.raises(ConfigError, match="net.host_link.loss.p"):
        check_combinable([_info("a", False),
                          _info("b", False, **{"net.host_link.loss.p": 0.02})])
    other = _info("b", False)
    other["cores"] = 4
    with pytest.raises(ConfigError, match="^cores"):
        check_combinable([_info("a", False), other])


def test_under_load_warning() -> None:
    busy = _info("r", False)
    busy["background"] = 0.62
    assert "0.62 of its 2 cores" in (under_load_warning(busy) or "")
    assert under_load_warning(_info("q", False)) is None  # 0.1 cores


def _fit(tmp: Path, name: str, up: list[float], bundle: bool, nodes: int = 4,
         **dep: float) -> tuple:  # type: ignore[type-arg]
    f = tmp / f"{name}_up.txt"
    np.savetxt(f, up)
    sc = load(None, [f"nodes={nodes}", "hosts=2"])
    d = replace(sc.deployment, preset="colocated", clients="host", bundle=bundle, **dep)
    link = replace(sc.net.host_link, latency=Dist(dist="empirical", file=str(f)))
    sc = replace(sc, deployment=d, net=replace(sc.net, host_link=link),
                 broker=replace(sc.broker, publish_service=Dist(dist="constant",
                                                                value=dep["host_demand"] / 10)))
    return sc, {"delivery_service_per_client_s": dep["host_demand"] / 5, "warnings": []}, \
        _info(name, bundle)


def test_combine_takes_each_parameter_from_the_runs_that_show_it(tmp_path: Path) -> None:
    fits = [_fit(tmp_path, "n20", [1e-3, 2e-3], False, host_demand=1e-4, host_record=1e-5),
            _fit(tmp_path, "b30", [9e-3], True, host_demand=3e-4, host_record=4e-5),
            _fit(tmp_path, "n60", [3e-3], False, host_demand=2e-4, host_record=2e-5)]
    sc, rep, primary = combine(fits, tmp_path)
    assert primary == 0
    # hops: the per-node runs' samples pooled (the bundled run's 9 ms left out)
    assert sorted(np.loadtxt(sc.net.host_link.latency.file)) == [1e-3, 2e-3, 3e-3]  # type: ignore[union-attr]
    # per message: the mean over the per-node runs; per record: the bundled run's
    assert sc.deployment.host_demand == pytest.approx(1.5e-4)
    assert sc.deployment.host_record == pytest.approx(4e-5)
    assert sc.broker.publish_service.value == pytest.approx(1.5e-5)
    assert rep["delivery_service_per_client_s"] == pytest.approx(3e-5)
    assert not sc.deployment.bundle  # the primary run's (per node)
    src = rep["parameter_sources"]
    assert src["per-record CPU of bundles"] == ["b30"]
    assert src["hop latencies (pooled samples)"] == ["n20", "n60"]
    assert src["step time, host share, scenario keys, cores"] == ["n20"]
    assert set(rep["runs"]) == {"n20", "b30", "n60"}


def test_two_per_node_runs_whose_mean_demand_is_below_the_first_runs_record(
        tmp_path: Path) -> None:
    """The first (primary) run's own record CPU (11 us) exceeds the mean demand of the
    two per-node runs (10 us): the combined deployment takes the mean demand and the
    bundled runs' record, clipped to that mean (it used to be refused as invalid)."""
    fits = [_fit(tmp_path, "r1", [1e-3], False, host_demand=1.2e-5, host_record=1.1e-5),
            _fit(tmp_path, "r2", [2e-3], False, host_demand=0.8e-5, host_record=0.8e-5),
            _fit(tmp_path, "b40", [3e-3], True, host_demand=1.3e-5, host_record=1.25e-5)]
    sc, _rep, _p = combine(fits, tmp_path)
    assert sc.deployment.host_demand == pytest.approx(1.0e-5)
    assert sc.deployment.host_record == pytest.approx(1.0e-5)  # 12.5 us clipped to 10


def test_cli_two_runs_in_sample_on_each_background_kept_apart(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = _cpu_run(tmp_path / "a", live={"cores": 4, "bundle": False, "load1": 0.5})
    b = _cpu_run(tmp_path / "b")  # bundled
    for run in (a, b):  # live figures for the in-sample check to compare with
        summ = json.loads((run / "summary.json").read_text())
        summ["methods"] = {"bides": {"aoi_mean": 20.0, "aoi_p99": 30.0,
                                     "latency_state_mean": 6.0, "trigger_rate_hz": 100.0,
                                     "missed_frac": 0.0}}
        (run / "summary.json").write_text(json.dumps(summ))
    out = tmp_path / "cal" / "cal.toml"
    assert main(["calibrate", str(a), str(b), "--out", str(out), "--no-match"]) == 0
    rep = json.loads(out.with_suffix(".json").read_text())
    assert {r["run"] for r in rep["in_sample"]} == {str(a), str(b)}
    assert rep["parameter_sources"]["per-record CPU of bundles"] == [str(b)]
    assert rep["background_cores_measured"] == pytest.approx(BACKGROUND_CPU / WINDOW)
    assert rep["deployment_background_cores"] == 0.0
    assert load(str(out)).deployment.background == 0.0  # the target's, not the run's
    assert "from " in capsys.readouterr().out
    assert main(["calibrate", str(a), "--out", str(out), "--no-match", "--no-check",
                 "--background", "0.5"]) == 0
    assert load(str(out)).deployment.background == 0.5
    capsys.readouterr()
    assert main(["calibrate", str(a), "--no-check", "--background", "4"]) == 2
    assert "--background" in capsys.readouterr().err
    summ = json.loads((b / "summary.json").read_text())
    summ["scenario"]["f_trig"] = 50.0
    (b / "summary.json").write_text(json.dumps(summ))
    assert main(["calibrate", str(a), str(b), "--no-check"]) == 2
    assert capsys.readouterr().err.startswith("sigma-des: error: f_trig: differs")
    assert math.isfinite(rep["background_cores_of_runs"][str(a)])


def test_combine_records_the_burst_of_the_pooled_hops(tmp_path: Path) -> None:
    """``hop_nodes_per_host``: the nodes per host of the runs whose hop samples were
    pooled, weighted by their states: 4 nodes on 2 hosts with 100 states and 12 on 2
    with 300 give (2 x 100 + 6 x 300) / 400 = 5; the bundled run (30 a host) is not
    one of them."""
    fits = [_fit(tmp_path, "a", [1e-3], False, host_demand=1e-4, host_record=1e-5),
            _fit(tmp_path, "b", [9e-3], True, nodes=60, host_demand=3e-4, host_record=4e-5),
            _fit(tmp_path, "c", [3e-3], False, nodes=12, host_demand=2e-4, host_record=2e-5)]
    for (_sc, rep, _inf), states in zip(fits, (100, 50, 300), strict=True):
        rep["states"] = states
    _sc, rep, _p = combine(fits, tmp_path)
    assert rep["hop_nodes_per_host"] == 5.0


def test_the_bundled_match_runs_on_the_first_bundled_run_of_a_per_node_campaign(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Hops matched on a per-node primary and a bundled run in the campaign: the bundled
    match runs on the first bundled run by name (its own fit and source), whatever the
    order given; a campaign whose
    primary is bundled, or without a bundled run, gets none."""
    from sigma_des.calibrate import cli, match

    seen: list[tuple[int, str]] = []
    got_sources: list[object] = []

    def fake(sc, report, own, source, name):  # type: ignore[no-untyped-def]
        seen.append((own.nodes, name))
        got_sources.append(source)
        return {"bundle_hop_scale": 1.5, "bundle_hop_nodes": float(own.nodes),
                "bundle_hop_run": name}

    monkeypatch.setattr(match, "match_bundled", fake)
    node = _fit(tmp_path, "n20", [1e-3], False, host_demand=1e-4)
    b1 = _fit(tmp_path, "b30", [1e-3], True, nodes=30, host_demand=1e-4)
    b2 = _fit(tmp_path, "b40", [1e-3], True, nodes=40, host_demand=1e-4)
    srcs = [tmp_path / "n20", tmp_path / "b30", tmp_path / "b40"]
    got = cli._match_bundled(node[0], {}, [node, b1, b2], srcs, 0)
    assert seen == [(30, "b30")] and got["bundle_hop_nodes"] == 30.0
    # a second bundled run of the first one's size and hosts: matched on both
    b3 = _fit(tmp_path, "b30b", [1e-3], True, nodes=30, host_demand=1e-4)
    both = cli._match_bundled(node[0], {}, [node, b1, b2, b3], [*srcs, tmp_path / "b30b"], 0)
    assert seen[-1] == (30, "b30, b30b") and both["bundle_hop_run"] == "b30, b30b"
    assert got_sources[-1] == [tmp_path / "b30", tmp_path / "b30b"]
    seen.pop()
    # given in another order: the same run (first by name) and the same sources
    again = cli._match_bundled(node[0], {}, [node, b3, b2, b1],
                               [tmp_path / "n20", tmp_path / "b30b", srcs[2], srcs[1]], 0)
    assert seen[-1] == (30, "b30, b30b") and again["bundle_hop_run"] == "b30, b30b"
    assert got_sources[-1] == [tmp_path / "b30", tmp_path / "b30b"]
    seen.pop()
    assert cli._match_bundled(b1[0], {}, [b1, node], srcs[1::-1], 0) == {}
    assert cli._match_bundled(node[0], {}, [node], srcs[:1], 0) == {}
    assert len(seen) == 1


def test_the_combined_figures_do_not_depend_on_the_order_of_the_runs(tmp_path: Path) -> None:
    """Pooled hop samples are sorted and means exactly rounded: given in another order,
    the same runs give the same samples (so the same draws) and bit-identical means.
    ``0.1 + 0.2 + 0.3`` summed left to right is 0.6000000000000001, right to left 0.6."""
    def fits(d: Path, order: list[int]) -> list[tuple]:  # type: ignore[type-arg]
        d.mkdir()
        made = [_fit(d, f"r{i}", [1e-3 * (i + 1), 5e-4 * i], False, host_demand=x,
                     host_record=x / 2) for i, x in enumerate((0.1, 0.2, 0.3))]
        return [made[i] for i in order]

    a, rep_a, _ = combine(fits(tmp_path / "a", [0, 1, 2]), tmp_path / "a")
    b, rep_b, _ = combine(fits(tmp_path / "b", [2, 1, 0]), tmp_path / "b")
    assert a.deployment.host_demand == b.deployment.host_demand == 0.6 / 3
    assert np.loadtxt(a.net.host_link.latency.file).tolist() == \
        np.loadtxt(b.net.host_link.latency.file).tolist() == [0.0, 5e-4, 1e-3, 1e-3, 2e-3, 3e-3]  # type: ignore[union-attr]
    for key in ("delivery_service_per_client_s", "hop_nodes_per_host"):
        assert rep_a[key] == rep_b[key]
    assert a.broker.publish_service.value == b.broker.publish_service.value


def test_a_second_campaign_in_the_same_folder_pools_its_own_samples(tmp_path: Path) -> None:
    """The pooled hop file is written by each combine: one left in the folder by an
    earlier campaign of other runs is not read back."""
    first = [_fit(tmp_path, f"a{i}", [1e-3 * (i + 1)], False, host_demand=1e-4)
             for i in range(2)]
    combine(first, tmp_path)
    second = [_fit(tmp_path, f"a{i}", [7e-3 + 1e-3 * i], False, host_demand=1e-4)
              for i in range(2)]  # the same run names, other samples
    sc, _rep, _p = combine(second, tmp_path)
    assert np.loadtxt(sc.net.host_link.latency.file).tolist() == [7e-3, 8e-3]  # type: ignore[union-attr]
