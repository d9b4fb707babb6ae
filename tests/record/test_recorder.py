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
    with Recorder(path, scenario={"nodes": 2}, mode=mode, batch=3) as rec:
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
        assert topics["/none/state"] == "sigma_des.States"
        assert set(topics) == {f"/{m}/{k}" for m in ("none", "bides")
                               for k in ("trigger", "state", "command", "snapshot", "render")}
        assert all(s.encoding == "jsonschema" for s in summary.schemas.values())
        assert summary.chunk_indexes, "no chunk index: readers cannot seek"
        assert summary.statistics is not None
        # 8 triggers in batches of 3 -> 3 messages per method; states too; 4 commands -> 2
        by_topic = {summary.channels[c].topic: n
                    for c, n in summary.statistics.channel_message_counts.items()}
        assert by_topic["/none/trigger"] == 3 and by_topic["/none/command"] == 2
        msgs = list(reader.iter_messages(topics=["/bides/snapshot"]))
    body = json.loads(msgs[1][2].data)
    schema = SCHEMAS[("snapshot", "full")][1]
    _conforms(body, schema)
    assert body["timestamp"] == {"sec": 0, "nsec": 14_000_000}
    assert body["frame_id"] == "ned" and body["frame"] == 1 and body["frames"] == [1, 0]
    assert body["poses"][1]["position"] == {"x": 1.0, "y": 1.0, "z": -10.0}
    assert body["poses"][0]["orientation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
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


def test_attitude_becomes_the_quaternion_of_zyx_euler_angles(tmp_path: Path) -> None:
    from scipy.spatial.transform import Rotation

    path = tmp_path / "q.mcap"
    att = np.array([[0.1, -0.2, 0.3], [0.0, 0.0, math.pi / 2]])
    with Recorder(path) as rec:
        rec.run("none").snapshot(t=1.0, frame=5, frames=[5, 5], pos=np.zeros((2, 3)), att=att)
    with path.open("rb") as fh:
        body = json.loads(next(make_reader(fh).iter_messages())[2].data)
    want = Rotation.from_euler("ZYX", att[:, ::-1]).as_quat()
    got = np.array([[p["orientation"][c] for c in "xyzw"] for p in body["poses"]])
    np.testing.assert_allclose(got, want, atol=1e-12)


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


def test_unknown_schema_is_refused(tmp_path: Path) -> None:
    from mcap.writer import Writer

    path = tmp_path / "u.mcap"
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="sigma_des")
        w.add_metadata("sigma_des", {"recording": "{}", "scenario": "{}"})
        sid = w.register_schema("acme.Thing", "jsonschema", b"{}")
        cid = w.register_channel("/none/state", "json", sid)
        w.add_message(cid, 0, b"{}", 0)
        w.finish()
    with pytest.raises(RecordError, match="unknown schema 'acme.Thing'"):
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
