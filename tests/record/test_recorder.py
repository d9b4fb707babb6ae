"""The MCAP recorder and reader: every channel written and read back, exactly."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader

from sigma_des.record import Recorder, RecordError, open_recording, read_states, read_table
from sigma_des.record.schemas import SCHEMAS


def _write(path: Path, mode: str = "full") -> None:
    with Recorder(path, scenario={"nodes": 2}, mode=mode) as rec:
        for method in ("none", "bides"):
            run = rec.run(method, mode="des")
            for k in range(4):
                t = 0.01 * k
                for i in range(2):
                    run.trigger(frame=k, node=i, t_send=t, t_recv=t + 0.001 * (i + 1))
                    run.state(node=i, frame=k, t_send=t + 0.002, t_recv=t + 0.005,
                              pos=(k, i, -10.0), vel=(1.0, 0.0, 0.0), att=(0.0, 0.1, 0.2))
                run.command(node=1, frame=k, t_send=t, t_recv=t + 0.003, values=(1.5, math.nan))
                run.snapshot(t=t + 0.004, frame=k, frames=[k, k - 1],
                             pos=np.array([[k, 0.0, -10.0], [k, 1.0, -10.0]]))
                run.render(t=t + 0.006, aoi=[0.004, math.nan])


def test_every_channel_reads_back_exactly(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    _write(path)
    df = read_table(path)
    assert list(df.columns) == ["method", "kind", "node", "frame", "t_send", "t_recv"]
    counts = df.groupby(["method", "kind"]).size().to_dict()
    for m in ("none", "bides"):
        assert counts[(m, "trigger")] == 8 and counts[(m, "state")] == 8
        assert counts[(m, "command")] == 4 and counts[(m, "snapshot")] == 4
        assert counts[(m, "render")] == 4
    tr = df[(df.method == "bides") & (df.kind == "trigger")]
    assert tr.node.tolist() == [0, 1] * 4
    assert tr.frame.tolist() == [0, 0, 1, 1, 2, 2, 3, 3]
    assert np.allclose(tr.t_recv - tr.t_send, np.tile([0.001, 0.002], 4), atol=1e-15)
    sn = df[(df.method == "none") & (df.kind == "snapshot")]
    assert sn.frame.tolist() == [0, 1, 2, 3] and sn.node.isna().all()
    assert np.allclose(sn.t_recv, [0.004, 0.014, 0.024, 0.034]) and sn.t_send.isna().all()
    rd = df[(df.method == "none") & (df.kind == "render")]
    assert rd.node.isna().all() and rd.frame.isna().all()
    st = read_states(path, "bides")["bides"]
    assert st.node.tolist() == [0, 1] * 4
    assert st.pos[:, 0].tolist() == [0, 0, 1, 1, 2, 2, 3, 3]
    assert st.pos[:, 1].tolist() == [0, 1] * 4
    assert (st.vel == [1.0, 0.0, 0.0]).all() and (st.att == [0.0, 0.1, 0.2]).all()
    assert st.t_send[3] == 0.01 + 0.002 and st.t_recv[3] == 0.01 + 0.005


def test_file_layout_topics_schemas_and_indexes(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    _write(path)
    with path.open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None
        topics = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        assert topics["/bides/snapshot"] == "foxglove.PosesInFrame"
        assert topics["/none/state"] == "sigma_des.StateRows"
        assert set(topics) == {f"/{m}/{k}" for m in ("none", "bides")
                               for k in ("trigger", "state", "command", "snapshot", "render",
                                         "tf")}
        assert all(s.encoding == "jsonschema" for s in summary.schemas.values())
        assert summary.chunk_indexes, "no chunk index: readers cannot seek"
        assert summary.statistics is not None
        # one message per 10 ms window: frames k = 0..3 fall in windows 0..3
        by_topic = {summary.channels[c].topic: n
                    for c, n in summary.statistics.channel_message_counts.items()}
        assert by_topic["/none/trigger"] == 4 and by_topic["/none/command"] == 4
        msgs = list(reader.iter_messages(topics=["/bides/snapshot"]))
        trig = [m for _s, _c, m in reader.iter_messages(topics=["/none/trigger"])]
        cmd = json.loads(next(reader.iter_messages(topics=["/none/command"]))[2].data)
    assert [m.log_time for m in trig] == [10_000_000, 20_000_000, 30_000_000, 40_000_000]
    assert json.loads(trig[1].data) == {"t": 0.02, "rows": [
        {"node": 0, "frame": 1, "t_send": 0.01, "t_recv": 0.011},
        {"node": 1, "frame": 1, "t_send": 0.01, "t_recv": 0.012}]}
    # the NaN cell: 0 with valid 0, never null
    assert cmd["rows"] == [{"node": 1, "frame": 0, "t_send": 0.0, "t_recv": 0.003,
                            "values": [1.5, 0.0], "valid": [1, 0]}]
    body = json.loads(msgs[1][2].data)
    schema = SCHEMAS[("snapshot", "full")][1]
    _conforms(body, schema)
    assert body["timestamp"] == {"sec": 0, "nsec": 14_000_000}
    assert body["frame_id"] == "enu" and body["frame"] == 1 and body["frames"] == [1, 0]
    # NED (1, 1, -10): 1 m north, 1 m east, 10 m up -> ENU (1, 1, 10)
    assert body["poses"][1]["position"] == {"x": 1.0, "y": 1.0, "z": 10.0}
    assert body["poses"][0]["position"] == {"x": 0.0, "y": 1.0, "z": 10.0}
    h = math.sqrt(0.5)  # level, heading north: the FLU body turned +90 deg about ENU z
    q = body["poses"][0]["orientation"]
    assert [q[c] for c in "xyzw"] == pytest.approx([0.0, 0.0, h, h], abs=1e-15)
    assert msgs[1][2].log_time == 14_000_000


def _conforms(body: Any, schema: dict[str, Any]) -> None:
    """``body`` has only the schema's properties, with the schema's JSON types."""
    kinds = {"object": dict, "array": list, "string": str, "integer": int, "number": (int, float)}
    t = schema.get("type")
    if isinstance(t, str):
        assert isinstance(body, kinds[t]), (body, t)  # type: ignore[arg-type]
    if t == "object":
        props = schema["properties"]
        assert set(body) <= set(props), set(body) - set(props)
        for k, v in body.items():
            _conforms(v, props[k])
    if t == "array":
        for v in body:
            _conforms(v, schema["items"])


def test_log_time_never_decreases_across_methods_and_channels(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    _write(path)  # two methods written one after the other, no advance: sorted at close
    with path.open("rb") as fh:
        times = [m.log_time for _s, _c, m in make_reader(fh).iter_messages(log_time_order=False)]
    # per method: 4 windows x 3 bulk kinds, 4 snapshots, 4 swarm frames, 4 render samples
    assert len(times) == 2 * (4 * 3 + 4 + 4 + 4) and times == sorted(times)
    assert open_recording(path).runs["none"]["late_messages"] == "0"


def test_advance_writes_as_the_run_goes_and_counts_late_messages(tmp_path: Path) -> None:
    path = tmp_path / "a.mcap"
    with Recorder(path, window=0.1) as rec:
        run = rec.run("none")
        run.trigger(frame=0, node=0, t_send=0.0, t_recv=0.05)
        run.advance(0.1)  # window [0, 0.1) is due: written now
        assert rec._last_ns == 100_000_000
        run.trigger(frame=1, node=0, t_send=0.1, t_recv=0.15)
        run.advance(0.12)  # [0.1, 0.2) not due yet
        assert rec._last_ns == 100_000_000
        run.render(t=0.3, aoi=[0.2])
        run.advance(0.3)  # the window at 0.2, then the render at 0.3
        run.trigger(frame=0, node=1, t_send=0.0, t_recv=0.08)  # breaks the promise
    with path.open("rb") as fh:
        msgs = [(c.topic, m.log_time) for _s, c, m in make_reader(fh).iter_messages(
            log_time_order=False)]
    assert msgs == [("/none/trigger", 100_000_000), ("/none/trigger", 200_000_000),
                    ("/none/render", 300_000_000), ("/none/trigger", 300_000_000)]
    assert open_recording(path).runs["none"]["late_messages"] == "1"
    tr = read_table(path)
    assert tr[tr.kind == "trigger"].t_recv.tolist() == [0.05, 0.15, 0.08]  # own times kept


def test_non_finite_values_are_absent_or_flagged_never_null(tmp_path: Path) -> None:
    path = tmp_path / "n.mcap"
    with Recorder(path) as rec:
        run = rec.run("none")
        run.trigger(frame=0, node=-1, t_send=0.0, t_recv=math.nan)
        run.state(node=0, frame=0, t_send=0.0, t_recv=0.001, pos=(1.0, math.inf, 0.0),
                  vel=(0, 0, 0), att=(0, 0, math.nan))
        run.render(t=0.02, aoi=[0.004, math.nan])
    with path.open("rb") as fh:
        data = {c.topic: json.loads(m.data) for _s, c, m in make_reader(fh).iter_messages()}
    assert data["/none/trigger"]["rows"] == [{"node": -1, "frame": 0, "t_send": 0.0}]
    row = data["/none/state"]["rows"][0]
    assert "y" not in row and "psi" not in row and row["x"] == 1.0 and row["theta"] == 0.0
    assert data["/none/render"]["aoi"] == [0.004, -1.0]
    st = read_states(path)["none"]
    assert np.isnan(st.pos[0, 1]) and np.isnan(st.att[0, 2]) and st.pos[0, 0] == 1.0
    assert np.isnan(read_table(path).query("kind == 'trigger'").t_recv.iloc[0])


def test_attitude_is_drawn_in_enu_with_forward_left_up_bodies(tmp_path: Path) -> None:
    """Hand-computed: where the nose (body x) and the top (body z, FLU) point in ENU."""
    from scipy.spatial.transform import Rotation

    path = tmp_path / "q.mcap"
    att = np.array([[0.0, 0.0, math.pi / 2],  # level, heading east
                    [0.0, 0.3, 0.0],          # nose 0.3 rad up, heading north
                    [0.4, 0.0, 0.0]])         # right wing 0.4 rad down, heading north
    with Recorder(path) as rec:
        rec.run("none").snapshot(t=1.0, frame=5, frames=[5, 5, 5], pos=np.zeros((3, 3)),
                                 att=att)
    with path.open("rb") as fh:
        body = json.loads(next(make_reader(fh).iter_messages())[2].data)
    q = np.array([[p["orientation"][c] for c in "xyzw"] for p in body["poses"]])
    r = Rotation.from_quat(q)
    nose, top, left = r.apply([1.0, 0, 0]), r.apply([0, 0, 1.0]), r.apply([0, 1.0, 0])
    c, s = math.cos, math.sin
    np.testing.assert_allclose(nose, [[1, 0, 0], [0, c(0.3), s(0.3)], [0, 1, 0]], atol=1e-12)
    np.testing.assert_allclose(top, [[0, 0, 1], [0, -s(0.3), c(0.3)], [s(0.4), 0, c(0.4)]],
                               atol=1e-12)
    # rolled right: the top leans east, the left wing rises
    np.testing.assert_allclose(left[2], [-c(0.4), 0, s(0.4)], atol=1e-12)
    assert np.allclose(np.linalg.det(r.as_matrix()), 1.0)  # rotations: nothing mirrored


def test_enu_attitude_is_the_change_of_axes_of_the_ned_attitude() -> None:
    """R_z(pi/2 - psi) R_y(-theta) R_x(phi) == R(NED->ENU) R_ZYX(psi, theta, phi) R(FLU->FRD)."""
    from scipy.spatial.transform import Rotation

    from sigma_des.record.enu import enu_poses

    att = np.random.default_rng(3).uniform(-3.0, 3.0, (200, 3))
    ned_to_enu = Rotation.from_matrix([[0.0, 1, 0], [1, 0, 0], [0, 0, -1]])
    flu_to_frd = Rotation.from_matrix([[1.0, 0, 0], [0, -1, 0], [0, 0, -1]])
    want = ned_to_enu * Rotation.from_euler("ZYX", att[:, ::-1]) * flu_to_frd
    pos, q = enu_poses(np.array([[10.0, 20.0, -30.0]] * 200), att)
    assert (Rotation.from_quat(q) * want.inv()).magnitude().max() < 1e-12
    assert (q[:, 3] >= 0).all() and (pos == [20.0, 10.0, 30.0]).all()


def test_metadata_counts_and_run_mode(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    _write(path)
    rec = open_recording(path)
    assert rec.methods == ["none", "bides"] and rec.record_mode == "full"
    assert rec.scenario == {"nodes": 2}
    assert rec.runs["bides"]["states"] == "8" and rec.runs["bides"]["run_mode"] == "des"


@pytest.mark.parametrize(
    ("damage", "needle"),
    [
        ("truncate", "truncated"),
        ("garbage", "not a readable MCAP"),
        ("missing", "not found"),
        ("corrupt", "corrupt"),
    ],
)
def test_bad_files_raise_record_error_naming_the_file(tmp_path: Path, damage: str,
                                                      needle: str) -> None:
    path = tmp_path / "r.mcap"
    _write(path)
    data = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(b"hello, not an mcap file at all" * 10)
    elif damage == "missing":
        path.unlink()
    else:  # flip bytes inside the first chunk's compressed records
        b = bytearray(data)
        for j in range(200, 260):
            b[j] ^= 0xFF
        path.write_bytes(bytes(b))
    with pytest.raises(RecordError) as ei:
        read_table(path)
    assert ei.value.key == str(path) and needle in str(ei.value)


@pytest.mark.parametrize(("schema", "needle"), [
    ("acme.Thing", "unknown schema 'acme.Thing'"),
    ("sigma_des.States", "is the older column-batch layout"),  # written before issue 22
])
def test_unknown_or_older_schema_is_refused(tmp_path: Path, schema: str, needle: str) -> None:
    from mcap.writer import Writer

    path = tmp_path / "u.mcap"
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="sigma_des")
        w.add_metadata("sigma_des", {"recording": "{}", "scenario": "{}"})
        sid = w.register_schema(schema, "jsonschema", b"{}")
        cid = w.register_channel("/none/state", "json", sid)
        w.add_message(cid, 0, b"{}", 0)
        w.finish()
    with pytest.raises(RecordError, match=needle):
        read_table(path)


def test_existing_file_kept_unless_overwrite(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    path.write_bytes(b"keep me")
    with pytest.raises(FileExistsError):
        Recorder(path, overwrite=False)
    assert path.read_bytes() == b"keep me"


@pytest.mark.parametrize("mode", ["full", "incremental"])
def test_states_are_copied_from_reused_buffers(tmp_path: Path, mode: str) -> None:
    """The cohort core hands out views of buffers it overwrites (a one-row batch is one)."""
    path = tmp_path / "b.mcap"
    buf = np.zeros((1, 9))
    nodes = np.zeros((1, 2), dtype=np.int64)
    with Recorder(path, mode=mode, deadband_pos=0.0, deadband_vel=0.0,
                  deadband_att=0.0) as rec:
        run = rec.run("none")
        for k in range(5):
            buf[0, 0] = float(k)
            nodes[0, 1] = k
            run.states(nodes[:1, 0], nodes[:1, 1], buf[:1, 0] * 0.01, buf[:1, 0] * 0.01 + 1e-3,
                       buf[:1])
    st = read_states(path)["none"]
    assert st.pos[:, 0].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert st.frame.tolist() == [0, 1, 2, 3, 4]
