"""Live runs and signals: nothing finished is lost, nothing temporary is left behind.

Ctrl-C between methods or a second Ctrl-C during the clean-up keeps the methods that
finished; SIGTERM and SIGHUP stop a run as Ctrl-C does; whatever kills the parent,
even SIGKILL, the ``sigma-des-live-*`` and ``sigma-des-mqtt-*`` folders (the latter
holds the broker's password file) are removed. Each CLI test runs with a ``TMPDIR``
of its own, so a leftover is seen.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from sigma_des.live.broker import BrokerAddress
from sigma_des.live.runner import LiveOptions, run_live
from sigma_des.live.server import LiveServer
from sigma_des.live.wire import Topics
from tests.live.live_helpers import LIVE_SETS, live_scenario, needs_mosquitto

pytestmark = needs_mosquitto
ROOT = Path(__file__).resolve().parents[2]


def test_ctrl_c_between_methods_keeps_the_finished_ones() -> None:
    calls: list[str] = []

    def hook(addr: BrokerAddress, tp: Topics, srv: LiveServer) -> None:
        calls.append(srv.method)
        if len(calls) == 2:  # outside the run loop of the second method
            signal.raise_signal(signal.SIGINT)

    res, msgs, _ = run_live(live_scenario(), ["none", "bides", "hlc"], LiveOptions(hook=hook))
    assert calls == ["none", "bides"]  # hlc never started
    assert list(res.methods) == ["none"] and res.interrupted
    assert res.methods["none"]["snapshot_rate_hz"] > 0
    assert set(msgs["method"]) == {"none"}


def test_a_second_ctrl_c_during_the_clean_up_loses_nothing() -> None:
    def hook(addr: BrokerAddress, tp: Topics, srv: LiveServer) -> None:
        finish = srv.finish

        def finish_twice_interrupted() -> dict[str, Any]:
            signal.raise_signal(signal.SIGINT)  # the second Ctrl-C, while results are gathered
            return finish()

        srv.finish = finish_twice_interrupted  # type: ignore[method-assign]
        srv.loop.call_at(0.8, signal.raise_signal, signal.SIGINT)  # the first, mid-run

    res, _msgs, _ = run_live(live_scenario(), ["none", "bides"], LiveOptions(hook=hook))
    assert list(res.methods) == ["none"] and res.interrupted
    assert res.live["none"]["hosts_reported"] == [0, 1]  # the clean-up ran to its end
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def _live_cli(tmp_path: Path, *extra: str, methods: str = "none") -> subprocess.Popen[bytes]:
    """``sigma-des live`` in a subprocess with a TMPDIR of its own."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    sets = [a for s in LIVE_SETS[:2] for a in ("--set", s)]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(tmp)}
    return subprocess.Popen([sys.executable, "-m", "sigma_des.cli", "live", *sets, *extra,
                             "--methods", methods], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)


def _wait_running(p: subprocess.Popen[bytes], times: int = 1) -> None:
    """Read stderr until the ``times``-th 'hosts ready, running' line."""
    assert p.stderr is not None
    for _ in range(times):
        line = p.stderr.readline().decode()
        assert "hosts ready, running" in line, line


def _left(tmp_path: Path, wait: float = 10.0) -> list[str]:
    """What is left in the test's TMPDIR, polled (bounded) until it is empty."""
    deadline = time.monotonic() + wait
    while True:
        left = sorted(os.listdir(tmp_path / "tmp"))
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.1)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_stop_like_ctrl_c(tmp_path: Path, sig: signal.Signals) -> None:
    out = tmp_path / "out"
    p = _live_cli(tmp_path, "--set", "duration=30", "--out", str(out), "--no-plots")
    try:
        _wait_running(p)
        time.sleep(0.8)
        p.send_signal(sig)
        code = p.wait(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert code == 130
    summ = json.loads((out / "summary.json").read_text())
    assert summ["interrupted"] is True and list(summ["methods"]) == ["none"]
    assert _left(tmp_path, wait=0.0) == []


def test_sigkill_keeps_finished_methods_and_leaves_no_temp_folders(tmp_path: Path) -> None:
    out = tmp_path / "out"
    p = _live_cli(tmp_path, "--set", "duration=1.5", "--out", str(out), "--no-plots",
                  methods="none,bides")
    try:
        _wait_running(p, times=2)  # the second method runs: the first was written
        kids = (tmp_path / "tmp").iterdir()
        assert {k.name.rsplit("-", 1)[0] for k in kids} == {"sigma-des-live", "sigma-des-mqtt"}
        p.kill()
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
    assert _left(tmp_path) == []  # the janitor removed them, password file included
    summ = json.loads((out / "summary.json").read_text())
    assert summ["interrupted"] is True and list(summ["methods"]) == ["none"]
    assert not [f for f in os.listdir(out) if f.startswith(".")]  # no half-written file


def test_ctrl_c_while_starting_prints_one_line(tmp_path: Path) -> None:
    p = _live_cli(tmp_path)
    time.sleep(0.3)  # loading the libraries
    p.send_signal(signal.SIGINT)
    code = p.wait(timeout=30)
    assert p.stderr is not None
    err = p.stderr.read().decode()
    # 130, or -2 (killed by SIGINT, which a shell shows as 130 too): CPython exits
    # that way when the interrupt landed in a module's import code, even once caught
    assert code in (130, -2) and "Traceback" not in err
    assert err.startswith("sigma-des: interrupted") and err.count("\n") == 1
    assert _left(tmp_path) == []


def test_record_and_out_after_ctrl_c_between_methods(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """``live --record --out`` interrupted between methods records and writes the first."""
    from dataclasses import replace

    from sigma_des.cli import main
    from sigma_des.live import runner
    from sigma_des.record import read_table

    real = runner.run_live
    calls: list[str] = []

    def hook(addr: BrokerAddress, tp: Topics, srv: LiveServer) -> None:
        calls.append(srv.method)
        if len(calls) == 2:
            signal.raise_signal(signal.SIGINT)

    def with_hook(sc: Any, methods: Any, opts: LiveOptions, **kw: Any) -> Any:
        return real(sc, methods, replace(opts, hook=hook), **kw)

    monkeypatch.setattr(runner, "run_live", with_hook)
    rec, out = tmp_path / "live.mcap", tmp_path / "out"
    sets = [a for s in LIVE_SETS for a in ("--set", s)]
    assert main(["live", *sets, "--methods", "none,bides", "--record", str(rec), "--out",
                 str(out), "--no-plots", "--no-progress"]) == 130
    assert json.loads((out / "summary.json").read_text())["interrupted"] is True
    table = read_table(rec)
    assert set(table["method"]) == {"none"} and len(table) > 0
