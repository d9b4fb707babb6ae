"""The frame to follow (``/<method>/tf``) and the Foxglove layout that follows it.

Each snapshot moves ``<method>/swarm`` (child of ``enu``) to the mean ENU position of
the snapshot's finite positions. Read back with the official ``mcap`` reader, checked
against hand-computed centres and the official ``foxglove.FrameTransform`` schema; the
layout names only topics and frames that a recording has.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
from conftest import tiny
from mcap.reader import make_reader

from sigma_des import compare
from sigma_des.cli import main
from sigma_des.record import Recorder, foxglove_layout, open_recording, read_table
from sigma_des.record.layout import LAYOUT_FILE, layout_json

DATA = Path(__file__).parent / "data"
OFFICIAL = json.loads((DATA / "foxglove.FrameTransform.json").read_text())
NAN = math.nan


def _messages(path: Path, topic: str) -> list[tuple[str, int, dict[str, Any]]]:
    """(schema name, log time, body) of every message on ``topic``, in file order."""
    with path.open("rb") as fh:
        return [(s.name, m.log_time, json.loads(m.data))
                for s, _c, m in make_reader(fh).iter_messages(topics=[topic])]


def _tiny_recording(path: Path, mode: str) -> None:
    with Recorder(path, scenario={"nodes": 3}, mode=mode) as rec:
        run = rec.run("hlc", mode="des")
        # NED (north, east, down); the third node has no position yet
        run.snapshot(t=0.5, frame=3, frames=[3, 3, -1],
                     pos=[[0.0, 0.0, -100.0], [10.0, 20.0, -110.0], [NAN, NAN, NAN]])
        run.snapshot(t=1.25, frame=7, frames=[7, 6, 7],
                     pos=[[4.0, -2.0, -90.0], [8.0, 2.0, -96.0], [-3.0, 6.0, -93.0]])
        run.snapshot(t=2.0, frame=8, frames=[-1, -1, -1], pos=np.full((3, 3), NAN))


@pytest.mark.parametrize("mode", ["full", "incremental"])
def test_the_swarm_frame_sits_at_the_hand_computed_centre(tmp_path: Path, mode: str) -> None:
    path = tmp_path / "tiny.mcap"
    _tiny_recording(path, mode)
    got = _messages(path, "/hlc/tf")
    # ENU = (east, north, -down): (0, 0, 100) and (20, 10, 110) -> centre (10, 5, 105);
    # (-2, 4, 90), (2, 8, 96), (6, -3, 93) -> (2, 3, 93); the all-NaN snapshot: none
    assert [(name, t) for name, t, _b in got] == [("foxglove.FrameTransform", 500_000_000),
                                                  ("foxglove.FrameTransform", 1_250_000_000)]
    ident = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    assert [b for _n, _t, b in got] == [
        {"timestamp": {"sec": 0, "nsec": 500_000_000}, "parent_frame_id": "enu",
         "child_frame_id": "hlc/swarm", "translation": {"x": 10.0, "y": 5.0, "z": 105.0},
         "rotation": ident},
        {"timestamp": {"sec": 1, "nsec": 250_000_000}, "parent_frame_id": "enu",
         "child_frame_id": "hlc/swarm", "translation": {"x": 2.0, "y": 3.0, "z": 93.0},
         "rotation": ident},
    ]
    official = jsonschema.Draft202012Validator(OFFICIAL)
    for _n, _t, body in got:
        assert list(official.iter_errors(body)) == []
    with path.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    (ch,) = [c for c in summary.channels.values() if c.topic == "/hlc/tf"]
    assert ch.message_encoding == "json"
    assert summary.schemas[ch.schema_id].encoding == "jsonschema"
    assert json.loads(summary.schemas[ch.schema_id].data)["title"] == "foxglove.FrameTransform"
    # the reader knows the channel; the tidy table lists the snapshots, not the frames
    assert open_recording(path).topics["/hlc/tf"] == ("hlc", "tf")
    assert set(read_table(path).kind) == {"snapshot"}


def test_the_official_schema_refuses_a_bad_transform() -> None:
    """The vendored schema is a real check: a transform without rotation is refused."""
    bad = {"timestamp": {"sec": 0, "nsec": 0}, "parent_frame_id": "enu",
           "child_frame_id": "hlc/swarm", "translation": {"x": 0.0, "y": 0.0, "z": 1.0}}
    assert list(jsonschema.Draft202012Validator(OFFICIAL).iter_errors(bad))


@pytest.fixture(scope="module", params=["full", "incremental"])
def recording(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
              ) -> Path:
    path = tmp_path_factory.mktemp(request.param) / "run.mcap"
    compare(tiny(record__mode=request.param), methods=["none", "bides"], progress=False,
            record=path)
    return path


def test_every_snapshot_moves_the_frame_to_its_centre(recording: Path) -> None:
    """One transform per snapshot, at its time; in full mode at its poses' mean."""
    full = open_recording(recording).record_mode == "full"
    for method in ("none", "bides"):
        snaps = _messages(recording, f"/{method}/snapshot")
        tfs = _messages(recording, f"/{method}/tf")
        assert len(tfs) == len(snaps) > 10
        for (_s, t_snap, snap), (_n, t_tf, tf) in zip(snaps, tfs, strict=True):
            assert t_tf == t_snap and tf["child_frame_id"] == f"{method}/swarm"
            assert 50 < tf["translation"]["z"] < 150  # the formation flies ~100 m up
            if full:
                assert tf["timestamp"] == snap["timestamp"]
                for c in "xyz":
                    mean = np.mean([p["position"][c] for p in snap["poses"]])
                    assert tf["translation"][c] == pytest.approx(mean, abs=1e-9)


def test_the_layout_names_what_the_recording_has(recording: Path) -> None:
    """Every topic and frame the shipped layout names is in a recording of bides."""
    layout = json.loads(LAYOUT_FILE.read_text())
    assert layout == foxglove_layout("bides")
    assert LAYOUT_FILE.read_text() == layout_json("bides")  # the shipped file is current
    three_d, plot, raw = (layout["configById"][k] for k in ("3D!swarm", "Plot!aoi",
                                                            "RawMessages!tf"))
    assert {layout["layout"]["first"], layout["layout"]["second"]["first"],
            layout["layout"]["second"]["second"]} == set(layout["configById"])
    topics = set(open_recording(recording).topics)
    named = {*three_d["topics"], raw["topicPath"],
             *(p["value"].split(".")[0] for p in plot["paths"])}
    assert named == {"/bides/snapshot", "/bides/tf", "/bides/render"}
    assert named <= topics
    (_s, _t, tf), *_ = _messages(recording, "/bides/tf")
    assert three_d["followTf"] == tf["child_frame_id"] == "bides/swarm"
    assert three_d["followMode"] == "follow-position"
    assert three_d["layers"]["ground"]["frameId"] == tf["parent_frame_id"] == "enu"
    render = next(open_recording(recording).messages("render", "bides"))
    assert plot["paths"][0]["value"] == "/bides/render.aoi[:]" and "aoi" in render


def test_the_layout_command_writes_any_method(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "hlc.json"
    assert main(["layout", "--method", "hlc", "--out", str(out)]) == 0
    assert json.loads(out.read_text()) == foxglove_layout("hlc")
    text = out.read_text()
    assert "/hlc/snapshot" in text and '"hlc/swarm"' in text and "bides" not in text
    capsys.readouterr()
    assert main(["layout"]) == 0
    assert json.loads(capsys.readouterr().out) == foxglove_layout("bides")
    assert main(["layout", "--method", "fastest"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sigma-des: error: --method") and "bides" in err
    assert len(err.splitlines()) == 1
    assert main(["layout", "--out", str(tmp_path)]) == 2  # a folder, not a file
    err = capsys.readouterr().err.strip()
    assert err.startswith("sigma-des: error: --out") and len(err.splitlines()) == 1


def test_incremental_snapshots_are_poses_at_display_precision(tmp_path: Path) -> None:
    """Full mode keeps the exact poses; incremental rounds them to 1 cm and 1e-4."""
    got = {}
    for mode in ("full", "incremental"):
        path = tmp_path / f"{mode}.mcap"
        with Recorder(path, mode=mode) as rec:  # NED: 10.123456 m north, 20.987654 m east
            rec.run("bides").snapshot(t=0.1, frame=1, frames=[1],
                                      pos=[[10.123456, 20.987654, -100.004]])
        ((name, _t, body),) = _messages(path, "/bides/snapshot")
        assert name == "foxglove.PosesInFrame" and body["frames"] == [1] and body["nodes"] == [0]
        got[mode] = body["poses"][0]
    h = math.sqrt(0.5)  # level, heading north
    assert got["full"]["position"] == {"x": 20.987654, "y": 10.123456, "z": 100.004}
    assert got["full"]["orientation"] == pytest.approx({"x": 0.0, "y": 0.0, "z": h, "w": h},
                                                       abs=1e-15)
    assert got["incremental"] == {"position": {"x": 20.99, "y": 10.12, "z": 100.0},
                                  "orientation": {"x": 0.0, "y": 0.0, "z": 0.7071, "w": 0.7071}}


def test_older_frame_only_snapshots_still_read(tmp_path: Path) -> None:
    """An incremental recording whose snapshots held only frames (no poses) reads."""
    from mcap.writer import Writer

    path = tmp_path / "older.mcap"
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="sigma_des", library="sigma_des (older)")
        w.add_metadata("sigma_des", {"recording": json.dumps({"record_mode": "incremental"}),
                                     "scenario": "{}"})
        sid = w.register_schema("sigma_des.SnapshotFrames", "jsonschema",
                                json.dumps({"type": "object", "properties": {}}).encode())
        cid = w.register_channel("/bides/snapshot", "json", sid)
        w.add_message(cid, 250_000_000, b'{"t":0.25,"frame":15,"frames":[15,14]}', 250_000_000)
        w.finish()
    df = read_table(path)
    assert df[["method", "kind", "frame", "t_recv"]].values.tolist() == [
        ["bides", "snapshot", 15.0, 0.25]]
