"""``compare --record``: what both engines record matches what the metrics measured."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import tiny

from sigma_des import compare
from sigma_des.cli import main
from sigma_des.record import open_recording, read_states, read_table


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[object, Path]]:
    out = {}
    for engine in ("cohort", "events"):
        path = tmp_path_factory.mktemp(engine) / "run.mcap"
        sc = tiny(engine=engine, commands__enabled=True, dynamics="quadrotor")
        res = compare(sc, methods=["none", "bides"], progress=False, record=path)
        out[engine] = (res, path)
    return out


@pytest.mark.parametrize("engine", ["cohort", "events"])
def test_recorded_states_match_the_measured_latency(recorded: dict, engine: str) -> None:
    res, path = recorded[engine]
    sc = res.scenario
    for method in ("none", "bides"):
        st = read_states(path, method)[method]
        late = st.t_send >= sc.warmup
        lat = (st.t_recv[late] - st.t_send[late]).mean() * 1000.0
        assert lat == pytest.approx(res.metric(method, "latency_state_mean"), rel=1e-12)
        assert st.node.size == sc.nodes * 100  # one state per node and trigger (1 s at 100 Hz)
        df = read_table(path)
        sn = df[(df.method == method) & (df.kind == "snapshot")]
        window = sc.duration - sc.warmup
        assert (sn.t_recv >= sc.warmup).sum() == round(res.metric(method, "snapshot_rate_hz")
                                                       * window)
        assert (df[(df.method == method)].kind == "render").sum() == 25  # 25 Hz for 1 s
        assert open_recording(path).runs[method]["late_messages"] == "0"


@pytest.mark.parametrize("engine", ["cohort", "events"])
def test_the_tap_writes_one_timeline_in_log_time_order(recorded: dict, engine: str) -> None:
    """Both engines keep the tap's promise: nothing late, log_time never decreases."""
    from mcap.reader import make_reader

    with recorded[engine][1].open("rb") as fh:
        times = [m.log_time for _s, _c, m in make_reader(fh).iter_messages(log_time_order=False)]
    assert len(times) > 100 and times == sorted(times)


def test_both_engines_record_the_same_states(recorded: dict) -> None:
    a = read_states(recorded["cohort"][1], "bides")["bides"]
    b = read_states(recorded["events"][1], "bides")["bides"]
    oa = np.lexsort((a.node, a.t_recv))
    ob = np.lexsort((b.node, b.t_recv))
    for f in ("node", "frame", "t_send", "t_recv", "pos", "vel", "att"):
        np.testing.assert_array_equal(getattr(a, f)[oa], getattr(b, f)[ob])


def test_triggers_and_commands_per_engine(recorded: dict) -> None:
    """Events engine: every delivery; cohort engine: the sends (see docs/concepts/model.md)."""
    ev = read_table(recorded["events"][1])
    co = read_table(recorded["cohort"][1])
    n = 3
    tr_ev = ev[(ev.method == "none") & (ev.kind == "trigger")]
    tr_co = co[(co.method == "none") & (co.kind == "trigger")]
    assert len(tr_ev) == n * len(tr_co) == n * 100
    assert (tr_co.node == -1).all() and tr_co.t_recv.isna().all()
    assert set(tr_ev.node) == {0, 1, 2} and (tr_ev.t_recv > tr_ev.t_send).all()
    np.testing.assert_array_equal(np.sort(tr_co.t_send.unique()), np.sort(tr_ev.t_send.unique()))
    cm_ev = ev[(ev.method == "none") & (ev.kind == "command")]
    cm_co = co[(co.method == "none") & (co.kind == "command")]
    assert len(cm_ev) == len(cm_co) > 0 and cm_co.t_recv.isna().all()
    assert (cm_ev.t_recv > cm_ev.t_send).all()


def test_jobs_2_records_the_same_file_content(recorded: dict, tmp_path: Path) -> None:
    res, path = recorded["cohort"]
    p2 = tmp_path / "j2.mcap"
    compare(res.scenario, methods=["none", "bides"], progress=False, jobs=2, record=p2)
    assert read_table(p2).equals(read_table(path))
    assert open_recording(p2).runs == open_recording(path).runs
    assert not list(tmp_path.glob(".*part"))


def test_cli_record_and_its_bad_paths(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sets = ["--set", "nodes=2", "--set", "hosts=1", "--set", "duration=0.3", "--set",
            "warmup=0.1", "--set", "dynamics=pointmass", "--methods", "none", "--no-progress"]
    p = tmp_path / "c.mcap"
    assert main(["compare", *sets, "--set", "record.mode=incremental", "--record", str(p)]) == 0
    assert open_recording(p).record_mode == "incremental"
    assert main(["compare", *sets, "--record", str(tmp_path / "c.txt")]) == 2
    assert "--record" in capsys.readouterr().err
    assert main(["compare", *sets, "--record", str(tmp_path / "no" / "c.mcap")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["compare", *sets, "--set", "record.mode=delta"]) == 2
    assert "record.mode" in capsys.readouterr().err
