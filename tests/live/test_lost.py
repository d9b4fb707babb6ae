"""A live method that loses hosts or its broker says so: a warning on stderr, the lost
hosts and the warning in ``summary.json``, instead of an unremarkable exit 0."""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from sigma_des.cli import main
from sigma_des.live.broker import Broker
from sigma_des.live.loop import Client
from sigma_des.live.lost import hop_notes, lost_notes
from sigma_des.live.runner import LiveOptions, run_live
from tests.live.live_helpers import LIVE_SETS, live_scenario, needs_mosquitto


def test_notes_of_a_complete_and_of_a_lossy_method() -> None:
    info: dict[str, Any] = {"hosts_reported": [0, 1], "hosts_killed": [], "missed_frac": 0.0}
    assert lost_notes(info, 2, False) == [] and info["lost_hosts"] == []
    info = {"hosts_reported": [0], "hosts_killed": [2], "missed_frac": 0.5}
    (note,) = lost_notes(info, 3, False)
    assert note.startswith("hosts 1, 2 of 3 sent no end-of-method report (host 2 died): ")
    assert note.endswith("missed_frac = 0.50") and info["lost_hosts"] == [1, 2]
    info = {"hosts_reported": [], "hosts_killed": [], "missed_frac": 0.71}
    down, every = lost_notes(info, 2, True)
    assert down.startswith("the broker connection was down when the method ended")
    assert every.startswith("every host of 2 sent no end-of-method report: ")


def _forged_stop(addr: Any, topics: Any, srv: Any) -> None:
    """A client holding the run's credentials ends the hosts 0.3 s into the method."""
    def stop() -> None:
        c = Client(addr, "forger", [], lambda t, p: None)
        c.start()
        c.publish(topics.ctl, b"stop", 1)
        c.stop()
    threading.Timer(0.3, stop).start()


@needs_mosquitto
def test_a_forged_stop_that_ends_every_host_is_flagged() -> None:
    res, _msgs, _ = run_live(live_scenario(), ["none"], LiveOptions(hook=_forged_stop))
    info = res.live["none"]
    assert info["hosts_reported"] == [] and info["lost_hosts"] == [0, 1]
    assert not res.interrupted
    (note,) = res.warnings()
    assert note.startswith("none: every host of 2 sent no end-of-method report")
    assert res.summary()["warnings"] == [note]


@needs_mosquitto
def test_an_external_broker_that_dies_for_good_is_flagged(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    broker = Broker()
    addr = broker.start()
    try:
        def kill_soon(_addr: Any, _topics: Any, _srv: Any) -> None:
            threading.Timer(0.5, broker.kill).start()  # SIGKILL, never restarted

        sets = [a for s in [*LIVE_SETS, "duration=2.0"] for a in ("--set", s)]
        out = tmp_path / "out"

        def with_hook(**kw: Any) -> LiveOptions:  # the CLI's options, and the kill
            return LiveOptions(**kw, hook=kill_soon)

        monkeypatch.setattr("sigma_des.live.runner.LiveOptions", with_hook)
        rc = main(["live", *sets, "--methods", "none", "--broker",
                   f"{addr.host}:{addr.port}", "--username", addr.username, "--password",
                   addr.password, "--no-progress", "--no-plots", "--out", str(out)])
    finally:
        broker.stop()
    assert rc == 0
    err = capsys.readouterr().err
    assert "sigma-des: warning: none: the broker connection was down when the method ended" in err
    assert "sigma-des: warning: none: every host of 2 sent no end-of-method report" in err
    summ = json.loads((out / "summary.json").read_text())
    assert summ["live"]["none"]["lost_hosts"] == [0, 1]
    assert summ["interrupted"] is False
    down, every = summ["warnings"][:2]  # and, under load, perhaps a slow-hop note
    assert down.startswith("none: the broker connection was down when the method ended")
    assert every.startswith("none: every host of 2 sent no end-of-method report")


def _states(latencies: list[float], republish: bool = False) -> pd.DataFrame:
    return pd.DataFrame({"kind": "state", "t_send": 1.0, "t_recv": [1.0 + x for x in latencies],
                         "republish": republish})


def test_a_slow_broker_hop_is_flagged() -> None:
    sc = live_scenario()  # links: 0.25 ms up + 0.25 ms down
    # median 40.5 ms: Nagle's algorithm and a 40 ms delayed ACK on the broker's sends
    (note,) = hop_notes(_states([0.0006, 0.0405, 0.041]), sc, impair=True)
    assert note.startswith("the broker hop took 40.0 ms (median state latency 40.5 ms less "
                           "the links' 0.50 ms), far above")
    assert "set_tcp_nodelay true" in note
    assert hop_notes(_states([0.0006, 0.0009, 0.041]), sc, impair=True) == []
    # without the links' latencies (--no-impair) the whole latency is the hop
    assert hop_notes(_states([0.0052] * 3), sc, impair=True) == []
    assert len(hop_notes(_states([0.0052] * 3), sc, impair=False)) == 1
    assert hop_notes(_states([0.05] * 3, republish=True), sc, impair=True) == []
