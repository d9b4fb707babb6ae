"""`calibrate` on synthetic live runs: per-direction hop latencies with hand-computed
values, the step time without its wait for a core, refusal and warnings on incomplete
inputs, and the in-sample check's errors and flags."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sigma_des import load
from sigma_des.api import run_method
from sigma_des.calibrate.dequeue import job_services
from sigma_des.calibrate.fit import STALL_FACTOR, calibrate, report_lines, stalls
from sigma_des.calibrate.insample import TOLERANCE, in_sample, missed_frac
from sigma_des.cli import main
from sigma_des.config import Scenario, to_dict
from sigma_des.errors import ConfigError
from sigma_des.live.messages import write_messages
from sigma_des.live.runner import MESSAGE_COLUMNS

SETS = ["nodes=4", "hosts=2", "duration=2.0", "warmup=0.5", "seed=3"]
STATE_LAT = 0.006  # every state: 6 ms
TRIG_LAT = (0.002, 0.00201)  # host 0 gets each trigger after 2 ms, host 1 10 us later
PUBLISH = 4e-6  # the base scenario's broker publish service
DELIVERY = 1e-5  # the gap between the two receivers


def _run(sc: Scenario, method: str = "bides") -> pd.DataFrame:
    """A clean synthetic live run: 100 Hz triggers, node i publishes 1 + 0.5 i ms after
    its host got the trigger (4 nodes on 8 cores: no core wait), states take 6 ms."""
    rows = []
    for k in range(int(sc.duration * sc.f_trig)):
        t = k / sc.f_trig
        rows.append(("trigger_sent", -1, -1, k, t, math.nan, math.nan, 0.0))
        for h in range(sc.hosts):
            rows.append(("trigger", h, -1, k, t, t + TRIG_LAT[h], math.nan, 0.0))
        for i in range(sc.nodes):
            h = sc.host_of[i]
            got = t + TRIG_LAT[h]
            pub = got + 0.001 + 0.0005 * i
            rows.append(("state_pub", h, i, k, pub, math.nan, got, 0.0008))
            rows.append(("state", h, i, k, pub, pub + STATE_LAT, pub + STATE_LAT, 0.0))
    df = pd.DataFrame(rows, columns=list(MESSAGE_COLUMNS[1:-1]))
    return df.assign(method=method, republish=False)[list(MESSAGE_COLUMNS)]


def _write(d: Path, sc: Scenario, table: pd.DataFrame, methods: dict[str, object] | None = None
           ) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    write_messages(table, d)
    (d / "summary.json").write_text(json.dumps({"scenario": to_dict(sc),
                                                "methods": methods or {}}))
    return d


def test_job_services_take_out_the_wait_for_a_core() -> None:
    # 2 cores; nodes 0, 1, 2 triggered at 0 with services 1, 2, 1.5: node 2 waits for the
    # first free core (1.0) and publishes at 2.5; node 0's second job (trigger 0.5, while
    # busy) is requested at 1.0 and gets a core at 2.0 (node 2 holds the other until 2.5)
    got = job_services(host=[0, 0, 0, 0], node=[0, 1, 2, 0], t_req=[0.0, 0.0, 0.0, 0.5],
                       t_done=[1.0, 2.0, 2.5, 2.5], cores=2)
    assert got.tolist() == [1.0, 2.0, 1.5, 0.5]
    # hosts do not share cores
    got = job_services(host=[0, 1], node=[0, 1], t_req=[0.0, 0.0], t_done=[1.0, 1.0], cores=1)
    assert got.tolist() == [1.0, 1.0]


def test_job_services_find_a_nodes_previous_job_on_its_own_host_key() -> None:
    # two runs ("a/0", "b/0": methods whose clocks both start at 0) of node 0, one core:
    # in run b the job triggered at 0.1 ends at 1.1, in run a the one triggered at 0 ends
    # at 1.0. Each alone is a service of 1.0; looking for node 0's previous job across
    # both runs made b's job requested at a's end (1.0) and its service 0.1
    got = job_services(host=["a/0", "b/0"], node=[0, 0], t_req=[0.0, 0.1],
                       t_done=[1.0, 1.1], cores=1)
    assert got.tolist() == [1.0, 1.0]
    # within one run the rule still holds: the second job (trigger 0.5 while busy) is
    # requested when the first ends
    got = job_services(host=["a/0", "a/0"], node=[0, 0], t_req=[0.0, 0.5],
                       t_done=[1.0, 1.8], cores=1)
    assert got.tolist() == [1.0, pytest.approx(0.8)]


def test_calibrate_fits_each_direction_and_the_step_time(tmp_path: Path) -> None:
    sc = load(None, SETS)
    sc_cal, rep = calibrate(_write(tmp_path / "run", sc, _run(sc)), tmp_path / "files")
    assert rep["delivery_service_per_client_s"] == pytest.approx(DELIVERY, abs=1e-12)
    up = (STATE_LAT - PUBLISH - DELIVERY) / 2
    down = (np.mean(TRIG_LAT) - PUBLISH - DELIVERY) / 2
    net = sc_cal.net
    assert net.host_link.latency.file == net.server_link.latency_down.file  # type: ignore[union-attr]
    assert net.host_link.latency_down.file == net.server_link.latency.file  # type: ignore[union-attr]
    assert np.loadtxt(net.host_link.latency.file).mean() == pytest.approx(up, rel=1e-9)
    assert np.loadtxt(net.server_link.latency.file).mean() == pytest.approx(down, rel=1e-6)
    assert rep["state_held_frac"] == 0.0 and rep["down_held_frac"] == 0.0
    # node i publishes 1 + 0.5 i ms after its trigger: mean 1.75 ms (no core wait)
    assert rep["step_time_mean_s"] == pytest.approx(0.00175, rel=1e-9)
    assert sc_cal.compute.step_time.mean == pytest.approx(0.00175, rel=1e-9)
    assert rep["warnings"] == ["no cpu.csv next to the source: no CPU stage fitted "
                               "(deployment.preset 'none')"]


def test_missing_per_node_rows_are_refused_or_warned_about(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    sc = load(None, SETS)
    t = _run(sc)
    part = _write(tmp_path / "part", sc, t[~((t["kind"] == "state_pub") & (t["host"] == 1))])
    with pytest.raises(ConfigError, match=r"state_pub: no per-node publish rows .*bides/host1"):
        calibrate(part, tmp_path / "f1")
    _sc, rep = calibrate(part, tmp_path / "f1", strict=False)
    assert any("bides/host1" in w and "fitted from the other hosts" in w
               for w in rep["warnings"])
    assert rep["step_time_mean_s"] == pytest.approx(0.00125, rel=1e-9)  # host 0's nodes only
    # none at all: the base scenario's step time, said so
    none = _write(tmp_path / "none", sc, t[t["kind"] != "state_pub"])
    sc2, rep = calibrate(none, tmp_path / "f2", strict=False)
    assert sc2.compute == sc.compute
    assert any("kept from the base scenario (lognormal, mean 0.8 ms)" in w
               for w in rep["warnings"])
    # the CLI refuses with exit 2, one line naming the key
    assert main(["calibrate", str(part), "--out", str(tmp_path / "c.toml")]) == 2
    err = capsys.readouterr().err
    assert "state_pub: no per-node publish rows" in err and "Traceback" not in err
    assert main(["calibrate", str(part), "--out", str(tmp_path / "c.toml"),
                 "--allow-incomplete", "--no-check"]) == 0
    assert "warning: no per-node publish rows" in capsys.readouterr().err


def test_too_few_samples_and_one_host_are_warned_about(tmp_path: Path) -> None:
    sc = load(None, ["nodes=2", "hosts=1", "duration=2.0", "warmup=0.5"])
    t = _run(sc)
    # keep 5 trigger receipts in the window: too few for the down direction
    trig = t[(t["kind"] == "trigger") & (t["t_send"] >= 0.5)].index[5:]
    sc_cal, rep = calibrate(_write(tmp_path / "r", sc, t.drop(index=trig)), tmp_path / "f")
    w = " | ".join(rep["warnings"])
    assert "no trigger reached two hosts" in w and "kept the base's 6 µs per client" in w
    assert "only 5 trigger latencies" in w
    assert sc_cal.net.host_link.latency_down == sc_cal.net.host_link.latency
    # the base's fan-out time is kept: 3 us per node delivery
    assert sc_cal.broker.delivery_service.value == pytest.approx(3e-6)


def test_missed_frac_counts_node_frames_of_the_window() -> None:
    rows = [{"kind": "trigger", "node": -1, "frame": f, "t_send": 0.1 * f} for f in range(6)]
    # window [0.1, 0.5): frames 1..4, 2 nodes -> 8 states expected; 5 arrive (one twice)
    got = [(0, 1), (1, 1), (0, 2), (0, 3), (0, 3), (1, 4), (0, 0), (1, 5)]
    rows += [{"kind": "state", "node": n, "frame": f, "t_send": 0.0} for n, f in got]
    assert missed_frac(pd.DataFrame(rows), 2, 0.1, 0.5) == pytest.approx(1 - 5 / 8)
    assert math.isnan(missed_frac(pd.DataFrame(rows), 2, 5.0, 6.0))
    # the per-message engine's table: a trigger row per delivery (node >= 0), and a
    # Lock-Step re-request of frame 0 sent inside the window: the same frames count
    per_node = [{"kind": "trigger", "node": n, "frame": f, "t_send": 0.1 * f}
                for f in range(6) for n in range(2)]
    per_node += [{"kind": "trigger", "node": 1, "frame": 0, "t_send": 0.3}]
    states = [r for r in rows if r["kind"] == "state"]
    assert missed_frac(pd.DataFrame(per_node + states), 2, 0.1, 0.5) == pytest.approx(1 - 5 / 8)


def test_in_sample_errors_are_zero_on_the_des_itself_and_flag_a_miss(tmp_path: Path) -> None:
    sc = load(None, ["nodes=4", "hosts=2", "duration=1.0", "warmup=0.2"])
    rows0, _w = in_sample(sc, _write(tmp_path / "x", sc, _run(sc), {}))
    assert rows0 == []
    m = run_method(sc, "none")["metrics"]
    live = {**m, "missed_frac": 0.0, "aoi_mean": 2 * m["aoi_mean"]}
    rows, warn = in_sample(sc, _write(tmp_path / "y", sc, _run(sc), {"none": live}))
    got = {r["metric"]: r for r in rows}
    assert got["aoi_mean"]["error"] == pytest.approx(-0.5) and got["aoi_mean"]["flagged"]
    for k in ("aoi_p99", "latency_state_mean", "latency_trigger_mean", "trigger_rate_hz",
              "missed_frac"):
        assert got[k]["error"] == 0.0 and not got[k]["flagged"]
    assert warn == [f"none: the calibrated DES misses its own run by more than "
                    f"{TOLERANCE:.0%} on aoi_mean"]
    lines = report_lines({"in_sample": rows})
    assert "in-sample none aoi_mean: live" in lines[0] and lines[0].endswith("FLAGGED")
    assert lines[-1] == "in-sample: 5 of 6 cells within 10 % (10 pp)"


def test_hold_tol_is_validated(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sc = load(None, SETS)
    d = _write(tmp_path / "r", sc, _run(sc))
    assert main(["calibrate", str(d), "--hold-tol", "-0.001", "--no-check"]) == 2
    assert "--hold-tol: must be in 0..0.01 s, got -0.001" in capsys.readouterr().err
    # bursts of states 5 us apart: held at the default tolerance, kept as measured at 0
    t = _run(sc)
    st = t["kind"] == "state"
    t.loc[st, "t_recv"] -= (0.0005 - 5e-6) * t.loc[st, "node"]  # node i 5i us after node 0
    _sc, rep = calibrate(_write(tmp_path / "b", sc, t), tmp_path / "f")
    assert rep["state_held_frac"] == pytest.approx(0.75)  # all but the first of each frame
    _sc, rep0 = calibrate(_write(tmp_path / "b0", sc, t), tmp_path / "f0", hold_tol=0.0)
    assert rep0["state_held_frac"] == 0.0
    assert rep0["hop_latency_mean_s"] > rep["hop_latency_mean_s"]


def test_commands_leave_the_down_hop_to_the_triggers(tmp_path: Path) -> None:
    """A tick's commands leave the server together, so their latency (here 40 ms) holds
    its publish queue, which the DES adds itself: the down hop is the triggers' alone,
    the same with and without command rows."""
    sc = load(None, SETS)
    t = _run(sc)
    cmds = pd.DataFrame(
        [("command", sc.host_of[i], i, k, k / 60.0, k / 60.0 + 0.040, math.nan, 0.0)
         for k in range(int(sc.duration * 60)) for i in range(sc.nodes)],
        columns=list(MESSAGE_COLUMNS[1:-1])).assign(method="bides", republish=False)
    with_cmds = pd.concat([t, cmds[list(MESSAGE_COLUMNS)]], ignore_index=True)
    _sc0, rep0 = calibrate(_write(tmp_path / "a", sc, t), tmp_path / "fa")
    _sc1, rep1 = calibrate(_write(tmp_path / "b", sc, with_cmds), tmp_path / "fb")
    assert rep1["hop_down_latency_mean_s"] == rep0["hop_down_latency_mean_s"]
    assert rep1["down_latencies"] == rep0["down_latencies"]
    assert rep0["down_latency_mean_s"] == pytest.approx(np.mean(TRIG_LAT), rel=1e-9)


def test_stalls_hand_computed() -> None:
    """100 latencies: 99 at 1 ms and one at 50 ms. The 99th percentile (linear) is
    1 + 0.01·49 = 1.49 ms, the fence 14.9 ms: only the 50 ms one is a stall."""
    x = np.array([0.001] * 99 + [0.050])
    assert stalls(x).tolist() == [False] * 99 + [True]
    assert STALL_FACTOR * np.percentile(x, 99) == pytest.approx(0.0149)
    assert stalls(np.zeros(0)).size == 0


def test_a_stall_is_left_out_of_the_hop_draws_and_said(tmp_path: Path) -> None:
    """Three triggers of host 1 delayed 80 ms (one stall of its process): without the
    rule they would be drawn as per-hop latencies, recur at random and hold the stream
    behind them; they are left out (the hop is the clean run's) and reported."""
    sc = load(None, SETS)
    t = _run(sc)
    _sc0, rep0 = calibrate(_write(tmp_path / "a", sc, t), tmp_path / "fa")
    hit = t.index[(t["kind"] == "trigger") & (t["host"] == 1) & t["frame"].isin([100, 101, 102])]
    t.loc[hit, "t_recv"] += 0.080
    _sc1, rep1 = calibrate(_write(tmp_path / "b", sc, t), tmp_path / "fb")
    assert rep1["stalls_down"] == 3 and rep0["stalls_down"] == 0
    assert rep1["hop_down_latency_mean_s"] == pytest.approx(rep0["hop_down_latency_mean_s"],
                                                            rel=1e-3)
    assert any("3 of" in w and "process stalls" in w for w in rep1["warnings"])
