"""Live mode on a Dask cluster: a scheduler and two workers started here on 127.0.0.1.

Worker ``w1`` runs with its clock 1234.5 s ahead and 200 ppm fast (what a machine
without clock sync looks like to the server), so every run here checks the clock
reconciliation on real exchanges. The kill test comes last: it takes ``w1`` down.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cloudpickle
import numpy as np
import pandas as pd
import pytest

from sigma_des.cli import main
from sigma_des.live.broker import child_setup, free_port, wait_port
from sigma_des.live.runner import LiveOptions, run_live
from tests.live.live_helpers import LIVE_SETS, live_scenario, needs_mosquitto

pytest.importorskip("distributed")
pytestmark = [needs_mosquitto, pytest.mark.early]

OFFSET, DRIFT = 1234.5, 200e-6


class Cluster:
    """A ``dask scheduler`` and two ``dask worker`` processes (no nanny: a kill is a death)."""

    def __init__(self, d: Path) -> None:
        port = free_port()
        self.address = f"tcp://127.0.0.1:{port}"
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        dask = [sys.executable, "-m", "dask"]
        self._start("scheduler", d, [*dask, "scheduler", "--host", "127.0.0.1", "--port",
                                     str(port), "--no-dashboard"], {})
        if not wait_port("127.0.0.1", port, 60.0):
            raise RuntimeError("dask scheduler did not listen in 60 s")
        skew = {"SIGMA_DES_TEST_CLOCK_OFFSET": str(OFFSET), "SIGMA_DES_TEST_CLOCK_DRIFT":
                str(DRIFT)}
        for name, env in (("w0", {}), ("w1", skew)):
            self._start(name, d, [*dask, "worker", self.address, "--host", "127.0.0.1",
                                  "--name", name, "--nthreads", "1", "--no-nanny",
                                  "--no-dashboard", "--local-directory", str(d / name)], env)
        from distributed import Client

        with Client(self.address, timeout="30s") as c:
            c.wait_for_workers(2, timeout=60)

    def _start(self, name: str, d: Path, argv: list[str], env: dict[str, str]) -> None:
        log = open(d / f"{name}.log", "wb")
        self.procs[name] = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                            stdin=subprocess.DEVNULL,
                                            env={**os.environ, **env},
                                            preexec_fn=child_setup)  # dies with the tests
        log.close()

    def close(self) -> None:
        """SIGTERM every process, SIGKILL what is left after 10 s."""
        for p in self.procs.values():
            if p.poll() is None:
                p.terminate()
        deadline = time.monotonic() + 10.0
        for p in self.procs.values():
            try:
                p.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=5)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    c = Cluster(tmp_path_factory.mktemp("dask"))
    try:
        yield c
    finally:
        c.close()


def _alive(pid: int) -> bool:
    try:
        return "zombie" not in Path(f"/proc/{pid}/status").read_text().lower()
    except OSError:
        return False


def _sets(*extra: str) -> list[str]:
    return [a for s in [*LIVE_SETS, *extra] for a in ("--set", s)]


def test_hosts_on_both_workers_clocks_reconciled_and_calibrate_accepts(
        cluster: Cluster, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["live", *_sets("duration=3.0"), "--methods", "bides", "--scheduler",
                 cluster.address, "--out", str(out), "--no-plots", "--no-progress"]) == 0
    summ = json.loads((out / "summary.json").read_text())
    info = summ["live"]["bides"]
    assert [(w["host"], w["name"]) for w in info["where"]] == [(0, "w0"), (1, "w1")]
    assert len({w["worker"] for w in info["where"]}) == 2
    assert info["hosts_reported"] == [0, 1] and info["hosts_killed"] == []
    # a fault-free run rejects nothing: a host's own clock replies are not forged traffic
    assert info["rejected"] == 0 and summ["methods"]["bides"]["rejected"] == 0
    clock = info["clock"]
    for h, off in (("0", 0.0), ("1", OFFSET)):
        c = clock[h]
        true = off + (DRIFT if h == "1" else 0.0) * c["origin_s"]
        assert abs(c["offset_s"] - true) <= c["bound_s"] < 0.05, (h, c)
        assert c["exchanges"] >= 8 and c["kept"] >= 2
    m = summ["methods"]["bides"]
    assert 0.0 < m["latency_state_mean"] < 500.0 and m["aoi_mean"] > 0.0
    # the table's host times are on the server's clock; every negative latency is counted
    msgs = pd.read_csv(out / "messages.csv.gz")
    for h in (0, 1):
        trig = msgs[(msgs["kind"] == "trigger") & (msgs["host"] == h)]
        lat = trig["t_recv"] - trig["t_send"]
        assert len(trig) > 20 and abs(float(lat.median())) < 0.1, h
        rows = msgs[(msgs["host"] == h) & msgs["kind"].isin(["state", "trigger", "command"])]
        neg = int((rows["t_recv"] < rows["t_send"]).sum())
        assert clock[str(h)]["negative_latencies"] == neg
    cpu = pd.read_csv(out / "cpu.csv")  # each host's CPU, read on its worker
    assert list(cpu["process"]) == ["server", "host0", "host1", "broker", "background"]
    assert (cpu[cpu["process"].str.startswith("host")]["cpu_s"] > 0).all()
    assert main(["calibrate", str(out), "--out", str(tmp_path / "cal.toml"),
                 "--no-check"]) == 0


def test_unreachable_scheduler_exits_2_at_once_writing_nothing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    t = time.monotonic()
    code = main(["live", *_sets(), "--scheduler", f"tcp://127.0.0.1:{free_port()}", "--out",
                 str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and time.monotonic() - t < 10.0
    assert err.count("\n") == 0 and "--scheduler" in err and "no Dask scheduler" in err
    assert not out.exists()


def test_ctrl_c_keeps_partial_results_and_stops_every_remote_host(
        cluster: Cluster, tmp_path: Path) -> None:
    out = tmp_path / "out"
    placement = tmp_path / "placement.toml"  # pinned by name, the other way round
    placement.write_text('[hosts]\n0 = "w1"\n1 = { worker = "w0" }\n')
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    p = subprocess.Popen([sys.executable, "-m", "sigma_des.cli", "live", *_sets("duration=60"),
                          "--methods", "none", "--scheduler", cluster.address, "--placement",
                          str(placement), "--out", str(out), "--no-plots"], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert p.stderr is not None
        line = p.stderr.readline().decode()
        assert "hosts ready, running" in line, line
        time.sleep(1.0)
        p.send_signal(signal.SIGINT)
        code = p.wait(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert code == 130, p.stderr.read().decode(errors="replace")[-3000:] if p.stderr else ""
    summ = json.loads((out / "summary.json").read_text())
    assert summ["interrupted"] is True
    assert [w["name"] for w in summ["live"]["none"]["where"]] == ["w1", "w0"]
    pids = [w["pid"] for w in summ["live"]["none"]["where"]]
    assert len(pids) == 2 and all(pid > 0 for pid in pids)
    assert [pid for pid in pids if _alive(pid)] == []  # the hosts' processes are gone
    from distributed import Client

    with Client(cluster.address, timeout="30s") as c:  # and no task (actor) is left
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and c.run_on_scheduler(_tasks):
            time.sleep(0.2)
        assert c.run_on_scheduler(_tasks) == 0


def _tasks(dask_scheduler: Any) -> int:
    return sum(1 for k in dask_scheduler.tasks if "sigma-des-host" in str(k))


cloudpickle.register_pickle_by_value(sys.modules[__name__])  # _tasks runs on the scheduler


def test_bench_live_runs_its_cells_on_the_cluster(cluster: Cluster, tmp_path: Path) -> None:
    root = Path(__file__).resolve().parents[2]
    r = subprocess.run([sys.executable, str(root / "experiments" / "bench_live.py"), "--quick",
                        "--scheduler", cluster.address, "--paths", "dask", "--out",
                        str(tmp_path)], timeout=300,
                       capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(root)})
    assert r.returncode == 0, r.stderr[-2000:]
    rows = pd.read_csv(tmp_path / "bench_live.csv")
    assert list(rows["path"]) == ["dask"] and (rows["latency_state_mean"] > 0).all()
    assert rows["hosts_cores"].iloc[0] > 0  # the hosts' CPU, read on their workers
    assert "largest N held at 100 Hz: dask bundle bides:" in r.stdout


def test_worker_killed_mid_run_its_hosts_crash_and_the_run_goes_on(cluster: Cluster) -> None:
    w1 = cluster.procs["w1"]
    killed_at: list[float] = []

    def kill_w1_soon(_addr: Any, _topics: Any, srv: Any) -> None:
        def kill() -> None:
            killed_at.append(srv.loop.now)
            w1.kill()
        threading.Timer(0.8, kill).start()

    sc = live_scenario("duration=3.0", "warmup=0.2")
    res, msgs, _ = run_live(sc, ["bides"], LiveOptions(scheduler=cluster.address,
                                                       hook=kill_w1_soon))
    w1.wait(timeout=10)
    (t_kill,) = killed_at
    assert t_kill < 2.0, t_kill
    info = res.live["bides"]
    assert info["hosts_killed"] == [1] and info["hosts_reported"] == [0]
    host1 = info["where"][1]["pid"]
    deadline = time.monotonic() + 10.0
    while _alive(host1) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(host1)  # died with its worker
    # host 1's nodes (2 and 3) fell silent; BiDES excludes them and keeps advancing
    st = msgs[msgs["kind"] == "state"]
    assert st[st["node"] >= 2]["t_recv"].max() < t_kill + 0.5
    assert st[st["node"] < 2]["t_recv"].max() > t_kill + 0.8
    ts = res.timeseries["bides"]
    assert ts["aligned_frame"][-1] > ts["aligned_frame"][np.searchsorted(ts["t"], t_kill)] + 20
    assert res.methods["bides"]["missed_frac"] > 0.1
