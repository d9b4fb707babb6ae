"""Live runs on a real broker: all four methods, the output files, calibration, CLI errors."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sigma_des.calibrate.insample import IN_SAMPLE_METRICS
from sigma_des.calibrate.match import MATCH_ROUNDS, MATCH_TOL
from sigma_des.cli import main
from sigma_des.config import load
from sigma_des.live.wire import STATE_BYTES
from tests.live.live_helpers import LIVE_SETS, needs_mosquitto

pytestmark = needs_mosquitto


@pytest.fixture(scope="module")
def live_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("live")
    sets = [a for s in LIVE_SETS for a in ("--set", s)]
    assert main(["live", *sets, "--out", str(out)]) == 0
    return out


def test_writes_compares_files_with_mode_live(live_dir: Path) -> None:
    summ = json.loads((live_dir / "summary.json").read_text())
    assert summ["mode"] == "live" and summ["interrupted"] is False
    # CPU of every process over the idle and the metrics windows (cpu.csv = summary's rows)
    cpu = pd.read_csv(live_dir / "cpu.csv")
    assert len(cpu) == 4 * 5 and set(cpu["process"]) == {"server", "host0", "host1", "broker",
                                                         "background"}
    assert (cpu["window_s"] > 0).all() and (cpu["idle_s"] >= 0.9).all()  # idle window 1 s
    srv = cpu[(cpu["method"] == "bides") & (cpu["process"] == "server")].iloc[0]
    assert summ["live"]["bides"]["cpu"][0]["cpu_s"] == pytest.approx(srv["cpu_s"])
    assert set(summ["methods"]) == {"none", "lockstep", "hlc", "bides"}
    rows = pd.read_csv(live_dir / "results.csv")
    assert set(rows["method"]) == {"none", "lockstep", "hlc", "bides"}
    # the same files as compare: the run-cost table and the plots too
    assert set(pd.read_csv(live_dir / "wall.csv")["metric"]) >= {"wall_s"}
    assert (live_dir / "aoi_time.png").stat().st_size > 1000
    for m, ms in summ["methods"].items():
        assert ms["latency_state_mean"] > 0, m
        assert ms["aoi_mean"] > 0, m
        assert ms["rejected"] == 0 and ms["unknown_topic"] == 0
        assert summ["live"][m]["hosts_killed"] == []
        # fidelity from the hosts' true positions against the ideal run
        assert 0.0 <= ms["formation_err_mean"] <= ms["formation_err_max"] < 50.0
        assert ms["dtw_r"] >= 0.0
        assert summ["live"][m]["hosts_reported"] == [0, 1]
    # BiDES and Lock-Step show one frame for everyone whenever no node was excluded
    # (extrapolated), live as in the DES
    for m in ("bides", "lockstep"):
        ms = summ["methods"][m]
        assert ms["spread_mean"] == 0.0 or ms["extrapolated_frac"] > 0, m


def test_message_table_is_consistent_with_the_metrics(live_dir: Path) -> None:
    msgs = pd.read_csv(live_dir / "messages.csv.gz")
    summ = json.loads((live_dir / "summary.json").read_text())
    sc = load(None, LIVE_SETS)
    for m, g in msgs.groupby("method"):
        # first copy of each (kind, node, frame), republished Lock-Step states a kind of
        # their own, as the collector counts them
        st = g[g["kind"] == "state"]
        first = st.drop_duplicates(["republish", "node", "frame"])
        first = first[first["t_send"] >= sc.warmup]
        lat = (first["t_recv"] - first["t_send"]).mean() * 1000.0
        assert lat == pytest.approx(summ["methods"][m]["latency_state_mean"], rel=1e-6)
        trig = g[g["kind"] == "trigger"]
        assert set(trig["host"]) == {0, 1}
        assert (trig["t_recv"] >= trig["t_send"]).all()
        sent = g[g["kind"] == "trigger_sent"]
        n_win = ((sent["t_send"] >= sc.warmup) & (sent["t_send"] < sc.duration)).sum()
        window = sc.duration - sc.warmup
        assert n_win / window == pytest.approx(summ["methods"][m]["trigger_rate_hz"])


def test_throughput_is_the_ledgers_bytes(live_dir: Path) -> None:
    summ = json.loads((live_dir / "summary.json").read_text())
    for m in summ["methods"]:
        links = summ["links_mbps"][m]
        assert {"server.up", "server.down", "host0.up", "host1.down"} <= set(links)
        assert sum(links.values()) == pytest.approx(summ["methods"][m]["throughput_mbps"])


def test_calibrate_writes_a_scenario_compare_runs(live_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "cal.toml"
    assert main(["calibrate", str(live_dir), "--out", str(out)]) == 0
    sc = load(str(out), ["duration=0.5", "warmup=0.1"])
    assert sc.net.host_link.latency.dist == "empirical"
    hop = np.loadtxt(sc.net.host_link.latency.file)
    assert hop.min() >= 0 and 0 < hop.mean() < 0.1
    down = sc.net.host_link.latency_down
    assert down is not None and down.file != sc.net.host_link.latency.file  # per direction
    assert sc.compute.step_time.dist == "lognormal"
    # the CPU stage is on: the live machine's deployment, fitted
    # (docs/concepts/live-and-calibration.md)
    summ = json.loads((live_dir / "summary.json").read_text())["live"]
    dep = sc.deployment
    assert (dep.preset, dep.clients, dep.server_tick) == ("colocated", "host", 0.0)
    assert dep.cores == len(os.sched_getaffinity(0)) == summ["bides"]["cores"]
    assert dep.bundle is False and summ["bides"]["bundle"] is False
    assert all(summ[m]["load1"] >= 0 for m in summ)
    assert sc.payload_bits == 8 * summ["bides"]["state_bytes"] == 8 * STATE_BYTES
    assert 0 < dep.host_demand < 0.01 and 0 < dep.server_demand < 0.01
    assert 0 <= dep.background < dep.cores
    pub, dlv = sc.broker.publish_service, sc.broker.delivery_service
    assert pub.dist == dlv.dist == "constant" and pub.value == dlv.value > 0
    assert 0.0 <= sc.compute.host_share <= 0.95
    # the report: CPU demands of every process and the in-sample errors of every method
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["host_demand_s"] == dep.host_demand and rep["broker_demand_s"] == pub.value
    assert rep["server_queue_folded_into_server_link"] is False
    methods = {"none", "lockstep", "hlc", "bides"}
    assert {(r["method"], r["metric"]) for r in rep["in_sample"]} == {
        (m, k) for m in methods for k in IN_SAMPLE_METRICS}
    assert all(np.isfinite(r["live"]) for r in rep["in_sample"])  # trigger latency included
    assert all(r["flagged"] == (abs(r["error"]) > 0.1) for r in rep["in_sample"])
    dem = {(r["method"], r["process"]): r for r in rep["cpu_demands"]}
    assert set(dem) == {(m, p) for m in methods for p in ("server", "host0", "host1", "broker")}
    for (m, p), r in dem.items():
        assert r["messages"] > 0 and r["busy_s"] == pytest.approx(
            r["cpu_s"] - r["idle_rate"] * r["window_s"])
        if p == "broker":  # every PUBLISH a client sent or received went through it
            assert r["messages"] == sum(dem[m, q]["messages"] for q in ("server", "host0", "host1"))
    assert set(rep["background_cores"]) == methods
    # the hops were matched to the run: the in-sample DES (the scenario written) gives
    # the match's last round, pooled over the methods, within its tolerance if it
    # stopped early
    ins = {(r["method"], r["metric"]): r["des"] for r in rep["in_sample"]}
    for metric, name in (("latency_state_mean", "hop_up"), ("latency_trigger_mean", "hop_down")):
        des = float(np.mean([ins[m, metric] for m in sorted(methods)]))
        assert des == pytest.approx(rep[f"{name}_des_ms"], rel=1e-9)
        if rep["hop_match_rounds"] < MATCH_ROUNDS:
            assert abs(des / rep[f"{name}_live_ms"] - 1) <= MATCH_TOL
    if rep["hop_match_rounds"] > 1:
        assert sc.net.host_link.latency.file.endswith("hop_up_matched.txt")
    # each kind's CPU was matched the same way, by its wake-ups' part beside the thread
    for kind in ("server", "host"):
        side = getattr(sc.deployment, f"{kind}_wake_side")
        assert side == rep[f"{kind}_wake_side_s"] * rep.get(f"{kind}_side_scale", 1.0)
        if f"{kind}_side_scale" in rep and rep["hop_match_rounds"] < MATCH_ROUNDS:
            assert abs(rep[f"{kind}_des_cores"] / rep[f"{kind}_live_cores"] - 1) <= MATCH_TOL
    # the prediction: the calibrated scenario runs with its CPU stage (the DES's CPU
    # metrics exist only then)
    pred = tmp_path / "pred"
    assert main(["compare", str(out), "--set", "duration=0.5", "--set", "warmup=0.1",
                 "--methods", "bides", "--no-progress", "--no-plots", "--out", str(pred)]) == 0
    got = json.loads((pred / "summary.json").read_text())["methods"]["bides"]
    assert 0 < got["server_cpu_util"] <= 1


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--methods", "nope"], "--methods: unknown method 'nope'"),
        (["--broker", "nohost"], "--broker: must be HOST:PORT"),
        (["--broker", "127.0.0.1:1"], "--broker: nothing accepts connections"),
        (["--set", 'faults=[{kind="drop", node=0, frame=3, message="state"}]'],
         "faults[0].kind: live mode runs 'crash' and 'slow'"),
        (["--set", "nodes=0"], "nodes: must be in"),
        (["--set", 'methods=["rpc"]'], "methods: live mode runs none, lockstep, hlc, bides"),
        (["--set", "net.middleware=dds", "--set", "net.transport=datagram", "--set",
          "net.qos=0"], "net.middleware: live mode runs over MQTT"),
        (["--record", "x.txt"], "--record: x.txt: the file name must end in .mcap"),
        (["--broker-port", "0"], "--broker-port: must be in 1..65535"),
    ],
)
def test_bad_input_exits_2_naming_the_key(args: list[str], needle: str,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["live", "--set", "duration=0.5", "--set", "warmup=0.1", *args]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_out_on_a_file_exits_2_before_running(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["live", "--set", "duration=0.5", "--set", "warmup=0.1", "--out", str(f)]) == 2
    assert "--out" in capsys.readouterr().err


def test_calibrate_bad_source_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["calibrate", str(tmp_path)]) == 2
    assert "messages.csv.gz" in capsys.readouterr().err


def test_external_broker_with_credentials(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    from sigma_des.live.broker import Broker

    with Broker() as addr:
        base = ["live", "--set", "nodes=2", "--set", "hosts=1", "--set", "duration=1.0",
                "--set", "warmup=0.2", "--methods", "none", "--broker",
                f"{addr.host}:{addr.port}", "--username", addr.username]
        assert main([*base, "--password", "wrong"]) == 2
        assert "--broker: MQTT connect" in capsys.readouterr().err
        secret = tmp_path / "secret"
        secret.write_text(addr.password + "\n")
        out = tmp_path / "out"
        assert main([*base, "--password-file", str(secret), "--no-progress", "--no-plots",
                     "--out", str(out)]) == 0
    summ = json.loads((out / "summary.json").read_text())
    assert summ["methods"]["none"]["latency_state_mean"] > 0


def test_the_password_comes_from_the_option_the_file_or_the_environment(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import argparse

    from sigma_des.errors import ConfigError
    from sigma_des.live.cli import PASSWORD_ENV, password

    def ns(pw: str | None = None, pw_file: str | None = None) -> argparse.Namespace:
        return argparse.Namespace(password=pw, password_file=pw_file)

    monkeypatch.delenv(PASSWORD_ENV, raising=False)
    assert password(ns()) == ""
    monkeypatch.setenv(PASSWORD_ENV, "from-env")
    assert password(ns()) == "from-env"
    f = tmp_path / "pw"
    f.write_text("from-file\nignored\n")
    assert password(ns(pw_file=str(f))) == "from-file"
    assert password(ns(pw="from-option")) == "from-option"
    with pytest.raises(ConfigError, match="cannot go with --password"):
        password(ns("a", str(f)))
    with pytest.raises(ConfigError, match="cannot read"):
        password(ns(pw_file=str(tmp_path / "missing")))


class _FakeRun:
    """Records calls to the recorder contract's per-method writer (sigma_des.record)."""

    def __init__(self) -> None:
        self.calls: dict[str, list[dict[str, object]]] = {}

    def __getattr__(self, kind: str) -> object:
        if kind not in ("trigger", "state", "command", "snapshot", "render"):
            raise AttributeError(kind)
        return lambda **kw: self.calls.setdefault(kind, []).append(kw)


class _FakeRecorder:
    last: _FakeRecorder | None = None

    def __init__(self, path: str, scenario: dict[str, object], mode: str,
                 **settings: object) -> None:
        self.path, self.scenario, self.mode = path, scenario, mode
        self.runs: dict[str, tuple[str, _FakeRun]] = {}
        _FakeRecorder.last = self

    def __enter__(self) -> _FakeRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        pass

    def run(self, method: str, mode: str = "des") -> _FakeRun:
        r = _FakeRun()
        self.runs[method] = (mode, r)
        return r


def test_record_call_sites_follow_the_recorder_contract() -> None:
    from sigma_des.live.messages import record_messages
    from sigma_des.live.runner import LiveOptions, run_live

    sc = load(None, LIVE_SETS + ["fidelity.enabled=false"])
    res, msgs, kept = run_live(sc, ["bides"], LiveOptions(record=True))
    record_messages(_FakeRecorder, "x.mcap", res, msgs, kept)
    rec = _FakeRecorder.last
    assert rec is not None and rec.mode == "full" and rec.scenario["nodes"] == 4
    mode, run = rec.runs["bides"]
    assert mode == "live"
    c = run.calls
    trig = msgs[(msgs["kind"] == "trigger")]
    assert len(c["trigger"]) == 2 * len(trig)  # one per node of the receiving host (2 each)
    assert len(c["state"]) == int((msgs["kind"] == "state").sum())
    st = c["state"][0]
    assert set(st) == {"node", "frame", "t_send", "t_recv", "pos", "vel", "att"}
    assert len(st["pos"]) == len(st["vel"]) == len(st["att"]) == 3  # type: ignore[arg-type]
    assert c["command"] and len(c["command"][0]["values"]) == 4  # type: ignore[arg-type]
    snap = c["snapshot"][0]
    assert snap["pos"].shape == (4, 3)  # type: ignore[attr-defined]
    assert len(c["render"]) > 0 and c["render"][0]["aoi"].shape == (4,)  # type: ignore[attr-defined]


def test_live_record_reads_back_every_channel(tmp_path: Path) -> None:
    from sigma_des.record import read_table

    rec = tmp_path / "live.mcap"
    sets = [a for s in LIVE_SETS for a in ("--set", s)]
    assert main(["live", *sets, "--methods", "bides", "--out", str(tmp_path / "o"),
                 "--record", str(rec)]) == 0
    t = read_table(rec)
    msgs = pd.read_csv(tmp_path / "o" / "messages.csv.gz")
    counts = t.groupby("kind").size().to_dict()
    assert set(counts) == {"trigger", "state", "command", "snapshot", "render"}
    assert counts["trigger"] == 2 * int((msgs["kind"] == "trigger").sum())  # per node
    assert counts["state"] == int((msgs["kind"] == "state").sum())
    # commands are recorded as sent (with the host's receive time when it got them)
    assert counts["command"] >= int((msgs["kind"] == "command").sum()) > 0
    st = t[t["kind"] == "state"]
    assert (st["t_recv"] >= st["t_send"]).all() and set(st["method"]) == {"bides"}
    # calibration also reads a recording (the scenario from its metadata)
    assert main(["calibrate", str(rec), "--out", str(tmp_path / "cal.toml")]) == 0
    assert load(str(tmp_path / "cal.toml")).nodes == 4
