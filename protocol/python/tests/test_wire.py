"""The Python codec against WIRE.md's golden byte vectors: each decodes to the documented example and encodes
back to the same bytes. Run: python3 protocol/python/tests/test_wire.py (no zenoh needed)."""

import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from sinew_client import wire  # noqa: E402

SENDER = 0x0123456789ABCDEF
WIRE_MD = pathlib.Path(__file__).resolve().parents[2] / "WIRE.md"


def golden_vectors():
    vectors, name, text = {}, None, []
    for line in WIRE_MD.read_text().splitlines():
        if name is None and line.strip().startswith("```hex "):
            name, text = line.strip()[len("```hex ") :].strip(), []
        elif name is not None and line.strip() == "```":
            vectors[name] = bytes(int(pair, 16) for pair in " ".join(text).split())
            name = None
        elif name is not None:
            text.append(line)
    return vectors


def main():
    vectors = golden_vectors()
    assert len(vectors) >= 8, f"only {len(vectors)} golden vectors in {WIRE_MD}"
    for name, payload in vectors.items():
        sender, message = wire.decode(payload)
        assert sender == SENDER, (name, hex(sender))
        again = wire.encode(sender, message)
        assert again == payload, f"{name}: re-encoded differs\n{again.hex(' ')}\n{payload.hex(' ')}"
    _, pose = wire.decode(vectors["DevicePose"], wire.DevicePose)
    assert pose.seq == 1 and pose.device_time_ns == 1_000_000
    assert pose.position_mm == [1.0, 2.0, -3.5] and pose.render_mode == wire.RENDER_MODERATED
    _, force = wire.decode(vectors["ForceCommand-direct"], wire.ForceCommand)
    assert force.local_model is None and force.force_n == [0.0, 0.0, 1.5] and force.in_contact
    assert force.device_instance == 0x1122334455667788
    _, modelled = wire.decode(vectors["ForceCommand-local-model"], wire.ForceCommand)
    model = modelled.local_model
    assert model is not None and model.plane_count == 1 and model.planes[0].offset_mm == 4.0
    assert model.stiffness_n_per_mm[2] == 0.25
    _, hello = wire.decode(vectors["ParticipantHello"])
    assert hello.participant_id == "left" and hello.tool == "left-probe"
    assert math.isclose(hello.max_force_n, 3.3, rel_tol=1e-6)
    _, snapshot = wire.decode(vectors["SceneSnapshot"], wire.SceneSnapshot)
    assert snapshot.tools[0].shape == {"kind": "sphere", "radius_mm": 4.0}
    assert snapshot.tools[0].instrument == {"kind": "grasper", "jaw_length_mm": 8.0, "open_angle_rad": 0.5}
    assert snapshot.tool_states.tools[0].attachments == 12 and snapshot.tool_states.tools[0].jaw_angle_rad == 0.5
    assert snapshot.tool_states.threads[0].tool == 0
    nodes = snapshot.tool_states.threads[0].nodes_mm()
    expected = [[-18.0, 0.0, -2.0], [-16.0, 0.0, -2.5]]
    assert all(abs(a - b) < 1e-3 for n, e in zip(nodes, expected) for a, b in zip(n, e)), nodes
    hole = snapshot.tool_states.threads[0].holes[0]
    assert hole.position_mm == [-16.0, 0.0, -3.0] and hole.pull_n == 0.5 and not hole.on_needle
    assert snapshot.tool_states.needles[0].tool == 0
    assert snapshot.tool_states.needles[0].position_mm == [-18.0, 0.0, 3.0]
    assert snapshot.objects[0].bounds.dequantize([65535, 0, 32768])[0] == 40.0
    _, delta = wire.decode(vectors["MeshDelta"], wire.MeshDelta)
    assert delta.topology is not None and delta.topology.parents == [5] and delta.topology.added == [[301, 6, 7]]
    assert snapshot.objects[0].topology_epoch == 0
    _, stats = wire.decode(vectors["ServerStats"], wire.ServerStats)
    assert stats.devices[0].training.skill_state == "contact" and stats.exercise.kind == "suture"
    marks = stats.exercise.targets
    assert [(t.at_mm, t.radius_mm, t.hit) for t in marks] == [([10.0, 0.0, 0.0], 2.0, True), ([-10.0, 0.0, 0.0], 2.0, False)]
    # Bad input: clear errors, never a crash.
    for bad, why in [
        (b"", "truncated"),
        (vectors["DevicePose"][:20], "truncated"),
        (b"\x03\x00" + vectors["DevicePose"][2:], "version"),
        (vectors["DevicePose"] + b"\x00", "left over"),
    ]:
        try:
            wire.decode(bad)
        except wire.DecodeError as e:
            assert why in str(e), (why, str(e))
        else:
            raise AssertionError(f"accepted a payload that is {why}")
    try:
        wire.decode(vectors["DevicePose"], wire.ForceCommand)
    except wire.DecodeError as e:
        assert "expected" in str(e)
    else:
        raise AssertionError("accepted a pose as a force command")
    print(f"test_wire: {len(vectors)} golden vectors decode and re-encode exactly")


if __name__ == "__main__":
    main()
