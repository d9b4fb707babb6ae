"""Every channel of a recording passes the JSON-schema rules of Foxglove and Lichtblick.

Foxglove's and Lichtblick's ``parseJsonSchema`` turn a channel's JSON schema into
message definitions and refuse a channel (listing it under *Problems*) whose schema
has a field without one supported ``type`` (no unions such as ``["number", "null"]``,
no ``"null"``), an object without ``properties``, or an array whose items are neither
one scalar type nor objects (no arrays of arrays). :func:`foxglove_problems` restates
those rules; every message is then validated against its own embedded schema by the
independent ``jsonschema`` package, every snapshot against the official
``foxglove.PosesInFrame`` schema (``data/foxglove.PosesInFrame.json``) and every swarm
frame against the official ``foxglove.FrameTransform`` (``data/foxglove.FrameTransform.json``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from conftest import tiny
from mcap.reader import make_reader

from sigma_des import compare
from sigma_des.record.schemas import SCHEMAS

OFFICIAL = json.loads((Path(__file__).parent / "data" / "foxglove.PosesInFrame.json").read_text())
OFFICIAL_TF = json.loads((Path(__file__).parent / "data" / "foxglove.FrameTransform.json")
                         .read_text())
_SCALARS = ("boolean", "string", "number", "integer")


def foxglove_problems(schema: dict[str, Any], path: str = "") -> list[str]:
    """What Foxglove's JSON-schema parser would refuse in ``schema`` (an object type)."""
    if schema.get("type") != "object":
        return [f"{path or '<root>'}: expected type object, got {schema.get('type')!r}"]
    if not isinstance(schema.get("properties"), dict):
        return [f"{path or '<root>'}: object without properties"]
    out: list[str] = []
    for name, field in schema["properties"].items():
        p = f"{path}.{name}" if path else name
        if "oneOf" in field:
            if not all(isinstance(a.get("const"), int | float) for a in field["oneOf"]):
                out.append(f"{p}: oneOf alternatives must have number values")
            continue
        t = field.get("type")
        if t in _SCALARS:
            if t == "string" and field.get("contentEncoding") not in (None, "base64"):
                out.append(f"{p}: unsupported contentEncoding")
        elif t == "object":
            out += foxglove_problems(field, p)
        elif t == "array":
            item = field.get("items")
            it = item.get("type") if isinstance(item, dict) else None
            if it == "object":
                out += foxglove_problems(item, p + "[]")  # type: ignore[arg-type]
            elif it not in _SCALARS:
                out.append(f"{p}: unsupported type {json.dumps(it)} for array item")
        else:
            out.append(f"{p}: unsupported type {json.dumps(t)}")
    return out


def test_the_rules_refuse_what_foxglove_refused() -> None:
    """The two problems Foxglove listed for the column-batch layout are caught."""
    nullable = {"type": "object", "properties": {
        "t_recv": {"type": "array", "items": {"type": ["number", "null"]}}}}
    nested = {"type": "object", "properties": {
        "values": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}}}}
    assert foxglove_problems(nullable) == [
        't_recv: unsupported type ["number", "null"] for array item']
    assert foxglove_problems(nested) == ['values: unsupported type "array" for array item']
    assert foxglove_problems({"type": "object", "properties": {"a": {"type": "null"}}})
    assert foxglove_problems({"type": "object"}) == ["<root>: object without properties"]


@pytest.mark.parametrize("key", sorted(SCHEMAS))
def test_every_schema_passes_the_rules(key: tuple[str, str]) -> None:
    name, schema = SCHEMAS[key]
    assert foxglove_problems(schema) == [], name
    jsonschema.Draft202012Validator.check_schema(schema)


@pytest.fixture(scope="module", params=["full", "incremental"])
def recording(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
              ) -> Path:
    path = tmp_path_factory.mktemp(request.param) / "run.mcap"
    sc = tiny(engine="events", commands__enabled=True, dynamics="quadrotor",
              record__mode=request.param)
    compare(sc, methods=["none", "bides"], progress=False, record=path)
    return path


def test_every_channel_and_message_loads_under_foxglove_rules(recording: Path) -> None:
    with recording.open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None
        schemas = {sid: json.loads(s.data) for sid, s in summary.schemas.items()}
        for sid, schema in schemas.items():
            assert foxglove_problems(schema) == [], summary.schemas[sid].name
        validators = {sid: jsonschema.Draft202012Validator(s) for sid, s in schemas.items()}
        official = jsonschema.Draft202012Validator(OFFICIAL)
        official_tf = jsonschema.Draft202012Validator(OFFICIAL_TF)
        seen: dict[str, int] = {}
        last = -1
        for sch, ch, m in reader.iter_messages(log_time_order=False):
            body = json.loads(m.data)  # strict JSON: NaN or Infinity would fail here
            errors = [e.message for e in validators[ch.schema_id].iter_errors(body)]
            assert errors == [], (ch.topic, errors[:3])
            if sch is not None and sch.name == "foxglove.PosesInFrame":
                assert [e.message for e in official.iter_errors(body)] == [], ch.topic
                assert all(p["position"]["z"] > 0 for p in body["poses"])  # above ground
            if sch is not None and sch.name == "foxglove.FrameTransform":
                assert [e.message for e in official_tf.iter_errors(body)] == [], ch.topic
            assert m.log_time >= last, ch.topic  # one timeline
            last = m.log_time
            seen[ch.topic] = seen.get(ch.topic, 0) + 1
    kinds = ("trigger", "state", "command", "snapshot", "render", "tf")
    assert set(seen) == {f"/{m}/{k}" for m in ("none", "bides") for k in kinds}, seen


def test_the_official_schema_refuses_a_bad_snapshot() -> None:
    """The vendored schema is a real check: a pose without orientation is refused."""
    bad = {"timestamp": {"sec": 0, "nsec": 0}, "frame_id": "enu",
           "poses": [{"position": {"x": 0.0, "y": 0.0, "z": 1.0}}]}
    assert list(jsonschema.Draft202012Validator(OFFICIAL).iter_errors(bad))
