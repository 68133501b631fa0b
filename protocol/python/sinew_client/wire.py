"""The envelope and the postcard bodies of Sinew's messages (protocol 4), in pure Python.

Layout (protocol/WIRE.md): `[version u16 LE][kind u8][sender u64 LE][postcard body]`. Postcard writes unsigned
integers wider than a byte as LEB128 varints, floats as little-endian IEEE 754, bools as one byte, strings and
vectors as a varint length then the items, fixed arrays as their items, options and enums as a varint tag then
the value, structs as their fields in order. Each message class lists its fields in wire order in `FIELDS`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field, fields
from typing import Any, List, Optional

PROTOCOL_VERSION = 4
HEADER_LEN = 11

# Message kinds (the byte after the version).
KIND_DEVICE_POSE = 1
KIND_FORCE_COMMAND = 2
KIND_SCENE_SNAPSHOT = 3
KIND_MESH_DELTA = 4
KIND_TOOL_STATES = 5
KIND_SERVER_STATS = 6
KIND_PARTICIPANT_HELLO = 7

RENDER_DIRECT = 0
RENDER_MODERATED = 1
ROLE_SERVER = 0
ROLE_HAPTIC = 1
ROLE_VIEWER = 2


class DecodeError(ValueError):
    """A payload that is not the expected message: too short, another version or kind, a bad body."""


# ---- postcard primitives -------------------------------------------------------------------------------------


class _Reader:
    def __init__(self, data: bytes, at: int = 0):
        self.data = data
        self.at = at

    def take(self, n: int) -> bytes:
        if self.at + n > len(self.data):
            raise DecodeError(f"truncated body at byte {self.at} (needs {n} more)")
        out = self.data[self.at : self.at + n]
        self.at += n
        return out

    def varint(self, max_bits: int) -> int:
        value, shift = 0, 0
        while True:
            byte = self.take(1)[0]
            value |= (byte & 0x7F) << shift
            if byte & 0x80 == 0:
                break
            shift += 7
            if shift >= max_bits + 7:
                raise DecodeError(f"varint too long at byte {self.at}")
        if value >> max_bits:
            raise DecodeError(f"varint out of range for u{max_bits} at byte {self.at}")
        return value


def _varint(value: int) -> bytes:
    if value < 0:
        raise ValueError("unsigned value expected")
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


# A type is one of: "u8", "u16", "u32", "u64", "f32", "f64", "bool", "str", a message class (a struct),
# ("arr", T, n), ("vec", T), ("opt", T) and ("variants", [(name, [(field, T), ...]), ...]).


def _write(t: Any, value: Any, out: bytearray) -> None:
    if t == "u8":
        out.append(value)
    elif t in ("u16", "u32", "u64"):
        out += _varint(value)
    elif t == "f32":
        out += struct.pack("<f", value)
    elif t == "f64":
        out += struct.pack("<d", value)
    elif t == "bool":
        out.append(1 if value else 0)
    elif t == "str":
        raw = value.encode("utf-8")
        out += _varint(len(raw)) + raw
    elif isinstance(t, tuple) and t[0] == "arr":
        if len(value) != t[2]:
            raise ValueError(f"array of {t[2]} expected, got {len(value)}")
        for item in value:
            _write(t[1], item, out)
    elif isinstance(t, tuple) and t[0] == "vec":
        out += _varint(len(value))
        for item in value:
            _write(t[1], item, out)
    elif isinstance(t, tuple) and t[0] == "opt":
        if value is None:
            out.append(0)
        else:
            out.append(1)
            _write(t[1], value, out)
    elif isinstance(t, tuple) and t[0] == "variants":
        names = [name for name, _ in t[1]]
        tag = names.index(value["kind"])
        out += _varint(tag)
        for name, ft in t[1][tag][1]:
            _write(ft, value[name], out)
    else:
        for name, ft in t.FIELDS:
            _write(ft, getattr(value, name), out)


def _read(t: Any, r: _Reader) -> Any:
    if t == "u8":
        return r.take(1)[0]
    if t in ("u16", "u32", "u64"):
        return r.varint(int(t[1:]))
    if t == "f32":
        return struct.unpack("<f", r.take(4))[0]
    if t == "f64":
        return struct.unpack("<d", r.take(8))[0]
    if t == "bool":
        b = r.take(1)[0]
        if b > 1:
            raise DecodeError(f"bool byte {b} at {r.at - 1}")
        return b == 1
    if t == "str":
        n = r.varint(64)
        try:
            return r.take(n).decode("utf-8")
        except UnicodeDecodeError as e:
            raise DecodeError(f"string is not UTF-8: {e}") from e
    if isinstance(t, tuple) and t[0] == "arr":
        return [_read(t[1], r) for _ in range(t[2])]
    if isinstance(t, tuple) and t[0] == "vec":
        n = r.varint(64)
        if n > len(r.data) - r.at:
            raise DecodeError(f"vector of {n} items cannot fit in {len(r.data) - r.at} bytes")
        return [_read(t[1], r) for _ in range(n)]
    if isinstance(t, tuple) and t[0] == "opt":
        tag = r.take(1)[0]
        if tag == 0:
            return None
        if tag == 1:
            return _read(t[1], r)
        raise DecodeError(f"option tag {tag}")
    if isinstance(t, tuple) and t[0] == "variants":
        tag = r.varint(32)
        if tag >= len(t[1]):
            raise DecodeError(f"enum tag {tag} out of range")
        name, variant_fields = t[1][tag]
        value = {"kind": name}
        for fname, ft in variant_fields:
            value[fname] = _read(ft, r)
        return value
    return t(**{name: _read(ft, r) for name, ft in t.FIELDS})


V3 = ("arr", "f32", 3)
Q4 = ("arr", "f32", 4)
SYM3 = ("arr", "f32", 6)

# ---- messages ------------------------------------------------------------------------------------------------


@dataclass
class DevicePose:
    """Hapticserver -> server, 1 kHz, on sinew/<scene>/device/<id>/pose. Device frame, mm, mm/s, rad."""

    KIND = KIND_DEVICE_POSE
    seq: int = 0
    device_time_ns: int = 0
    position_mm: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    orientation_xyzw: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 1.0])
    linear_velocity_mm_s: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    buttons: int = 0
    jaw_angle_rad: float = 0.0
    round_trip_us: int = 0
    render_mode: int = RENDER_DIRECT


DevicePose.FIELDS = [
    ("seq", "u64"),
    ("device_time_ns", "u64"),
    ("position_mm", V3),
    ("orientation_xyzw", Q4),
    ("linear_velocity_mm_s", V3),
    ("buttons", "u32"),
    ("jaw_angle_rad", "f32"),
    ("round_trip_us", "u32"),
    ("render_mode", "u32"),  # enum RenderMode: its tag is a varint
]


@dataclass
class ContactPlane:
    """A unilateral plane of the local model: pushes out along `normal` below `offset_mm`."""

    normal: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    offset_mm: float = 0.0
    stiffness_n_per_mm: float = 0.0
    damping_n_s_per_mm: float = 0.0


ContactPlane.FIELDS = [
    ("normal", V3),
    ("offset_mm", "f32"),
    ("stiffness_n_per_mm", "f32"),
    ("damping_n_s_per_mm", "f32"),
]


@dataclass
class LocalModel:
    """The tissue near the tool: f = f0 - K (x - x0) - D v within the radius, plus planes (WIRE.md)."""

    server_time_ns: int = 0
    in_contact: bool = False
    x0_mm: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    f0_n: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    stiffness_n_per_mm: List[float] = field(default_factory=lambda: [0.0] * 6)
    damping_n_s_per_mm: List[float] = field(default_factory=lambda: [0.0] * 6)
    radius_mm: float = 0.0
    fade_mm: float = 0.0
    planes: List[ContactPlane] = field(default_factory=lambda: [ContactPlane() for _ in range(4)])
    plane_count: int = 0
    energy_allowance_mj: float = 0.0


LocalModel.FIELDS = [
    ("server_time_ns", "u64"),
    ("in_contact", "bool"),
    ("x0_mm", V3),
    ("f0_n", V3),
    ("stiffness_n_per_mm", SYM3),
    ("damping_n_s_per_mm", SYM3),
    ("radius_mm", "f32"),
    ("fade_mm", "f32"),
    ("planes", ("arr", ContactPlane, 4)),
    ("plane_count", "u8"),
    ("energy_allowance_mj", "f32"),
]


@dataclass
class ForceCommand:
    """Server -> hapticserver on sinew/<scene>/device/<id>/force. `local_model` None is ForceMode::Direct."""

    KIND = KIND_FORCE_COMMAND
    seq: int = 0
    echo_pose_seq: int = 0
    echo_device_time_ns: int = 0
    force_n: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    local_model: Optional[LocalModel] = None
    in_contact: bool = False
    device_instance: int = 0


ForceCommand.FIELDS = [
    ("seq", "u64"),
    ("echo_pose_seq", "u64"),
    ("echo_device_time_ns", "u64"),
    ("force_n", V3),
    # enum ForceMode { Direct = 0, LocalModel(LocalModel) = 1 }: the same bytes as an option.
    ("local_model", ("opt", LocalModel)),
    ("in_contact", "bool"),
    ("device_instance", "u64"),
]


@dataclass
class ParticipantHello:
    """Any participant -> everyone on sinew/<scene>/hello/<role>/<id>, on start and every second."""

    KIND = KIND_PARTICIPANT_HELLO
    participant_id: str = ""
    role: int = ROLE_HAPTIC
    device_model: str = ""
    max_force_n: float = 0.0
    tool: str = ""


ParticipantHello.FIELDS = [
    ("participant_id", "str"),
    ("role", "u32"),  # enum Role: 0 Server, 1 Haptic, 2 Viewer
    ("device_model", "str"),
    ("max_force_n", "f32"),
    ("tool", "str"),
]


@dataclass
class MeshDelta:
    """Server -> viewers: the changed vertices of one object, quantized against its snapshot bounds."""

    KIND = KIND_MESH_DELTA
    object: int = 0
    frame: int = 0
    prev_frame: int = 0
    indices: List[int] = field(default_factory=list)
    positions_q: List[List[int]] = field(default_factory=list)


MeshDelta.FIELDS = [
    ("object", "u16"),
    ("frame", "u64"),
    ("prev_frame", "u64"),
    ("indices", ("vec", "u32")),
    ("positions_q", ("vec", ("arr", "u16", 3))),
]


@dataclass
class ToolState:
    """One tool, world frame: position, orientation, the tissue's force on it."""

    tool: int = 0
    position_mm: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    orientation_xyzw: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0, 1.0])
    force_n: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    active: bool = False
    in_contact: bool = False


ToolState.FIELDS = [
    ("tool", "u16"),
    ("position_mm", V3),
    ("orientation_xyzw", Q4),
    ("force_n", V3),
    ("active", "bool"),
    ("in_contact", "bool"),
]


@dataclass
class ToolStates:
    """Server -> viewers on sinew/<scene>/tools, every publish frame."""

    KIND = KIND_TOOL_STATES
    frame: int = 0
    sim_time_s: float = 0.0
    tools: List[ToolState] = field(default_factory=list)


ToolStates.FIELDS = [("frame", "u64"), ("sim_time_s", "f64"), ("tools", ("vec", ToolState))]


@dataclass
class QuantBounds:
    min_mm: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    max_mm: List[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])

    def dequantize(self, q: List[int]) -> List[float]:
        return [self.min_mm[a] + q[a] / 65535.0 * (self.max_mm[a] - self.min_mm[a]) for a in range(3)]


QuantBounds.FIELDS = [("min_mm", V3), ("max_mm", V3)]


@dataclass
class ObjectSnapshot:
    object: int = 0
    name: str = ""
    bounds: QuantBounds = field(default_factory=QuantBounds)
    triangles: List[List[int]] = field(default_factory=list)
    positions_q: List[List[int]] = field(default_factory=list)
    frame: int = 0


ObjectSnapshot.FIELDS = [
    ("object", "u16"),
    ("name", "str"),
    ("bounds", QuantBounds),
    ("triangles", ("vec", ("arr", "u32", 3))),
    ("positions_q", ("vec", ("arr", "u16", 3))),
    ("frame", "u64"),
]

TOOL_SHAPE = (
    "variants",
    [
        ("sphere", [("radius_mm", "f32")]),
        ("capsule", [("half_length_mm", "f32"), ("radius_mm", "f32")]),
        ("mesh", [("positions_mm", ("vec", V3)), ("triangles", ("vec", ("arr", "u32", 3)))]),
    ],
)


@dataclass
class ToolInfo:
    tool: int = 0
    name: str = ""
    device_id: str = ""
    shape: dict = field(default_factory=lambda: {"kind": "sphere", "radius_mm": 1.0})


ToolInfo.FIELDS = [("tool", "u16"), ("name", "str"), ("device_id", "str"), ("shape", TOOL_SHAPE)]


@dataclass
class SceneSnapshot:
    """Server -> querier: the reply to a query on sinew/<scene>/snapshot."""

    KIND = KIND_SCENE_SNAPSHOT
    scene: str = ""
    frame: int = 0
    objects: List[ObjectSnapshot] = field(default_factory=list)
    tools: List[ToolInfo] = field(default_factory=list)
    tool_states: ToolStates = field(default_factory=ToolStates)


SceneSnapshot.FIELDS = [
    ("scene", "str"),
    ("frame", "u64"),
    ("objects", ("vec", ObjectSnapshot)),
    ("tools", ("vec", ToolInfo)),
    ("tool_states", ToolStates),
]


@dataclass
class RejectCounts:
    malformed: int = 0
    wrong_version: int = 0
    invalid: int = 0
    unknown_device: int = 0
    duplicate_device: int = 0
    wrong_tool: int = 0
    no_hello: int = 0


RejectCounts.FIELDS = [(f, "u64") for f in RejectCounts.__dataclass_fields__]


@dataclass
class TrainingStats:
    skill_state: str = ""
    contacts: int = 0
    contact_time_s: float = 0.0
    path_length_mm: float = 0.0
    peak_force_n: float = 0.0
    harm_n_s: float = 0.0


TrainingStats.FIELDS = [
    ("skill_state", "str"),
    ("contacts", "u64"),
    ("contact_time_s", "f32"),
    ("path_length_mm", "f32"),
    ("peak_force_n", "f32"),
    ("harm_n_s", "f32"),
]


@dataclass
class DeviceStats:
    device_id: str = ""
    active: bool = False
    poses_received: int = 0
    forces_sent: int = 0
    last_round_trip_us: int = 0
    max_force_n: float = 0.0
    moderated: bool = False
    forces_suppressed: int = 0
    tool: str = ""
    holder_instance: int = 0
    duplicates_refused: int = 0
    last_refused_instance: int = 0
    wrong_tool_instance: int = 0
    wrong_tool_asked: str = ""
    force_limit_n: float = 0.0
    training: TrainingStats = field(default_factory=TrainingStats)


DeviceStats.FIELDS = [
    ("device_id", "str"),
    ("active", "bool"),
    ("poses_received", "u64"),
    ("forces_sent", "u64"),
    ("last_round_trip_us", "u32"),
    ("max_force_n", "f32"),
    ("moderated", "bool"),
    ("forces_suppressed", "u64"),
    ("tool", "str"),
    ("holder_instance", "u64"),
    ("duplicates_refused", "u64"),
    ("last_refused_instance", "u64"),
    ("wrong_tool_instance", "u64"),
    ("wrong_tool_asked", "str"),
    ("force_limit_n", "f32"),
    ("training", TrainingStats),
]


@dataclass
class ExerciseStats:
    kind: str = ""
    score: float = 0.0
    hits: int = 0
    total: int = 0
    errors: int = 0
    time_s: float = 0.0
    completed: bool = False
    timed_out: bool = False


ExerciseStats.FIELDS = [
    ("kind", "str"),
    ("score", "f32"),
    ("hits", "u32"),
    ("total", "u32"),
    ("errors", "u32"),
    ("time_s", "f32"),
    ("completed", "bool"),
    ("timed_out", "bool"),
]


@dataclass
class ServerStats:
    """Server -> anyone on sinew/<scene>/stats, once a second."""

    KIND = KIND_SERVER_STATS
    sim_time_s: float = 0.0
    ticks: int = 0
    tick_p50_us: float = 0.0
    tick_p99_us: float = 0.0
    tick_max_us: float = 0.0
    overruns: int = 0
    sim_faults: int = 0
    deltas_sent: int = 0
    delta_bytes_sent: int = 0
    snapshots_served: int = 0
    quantization_clamps: int = 0
    rejected: RejectCounts = field(default_factory=RejectCounts)
    devices: List[DeviceStats] = field(default_factory=list)
    server_id: str = ""
    foreign_server_messages: int = 0
    foreign_server_instance: int = 0
    exercise: Optional[ExerciseStats] = None


ServerStats.FIELDS = [
    ("sim_time_s", "f64"),
    ("ticks", "u64"),
    ("tick_p50_us", "f32"),
    ("tick_p99_us", "f32"),
    ("tick_max_us", "f32"),
    ("overruns", "u64"),
    ("sim_faults", "u64"),
    ("deltas_sent", "u64"),
    ("delta_bytes_sent", "u64"),
    ("snapshots_served", "u64"),
    ("quantization_clamps", "u64"),
    ("rejected", RejectCounts),
    ("devices", ("vec", DeviceStats)),
    ("server_id", "str"),
    ("foreign_server_messages", "u64"),
    ("foreign_server_instance", "u64"),
    ("exercise", ("opt", ExerciseStats)),
]

MESSAGES = {
    cls.KIND: cls
    for cls in (
        DevicePose,
        ForceCommand,
        SceneSnapshot,
        MeshDelta,
        ToolStates,
        ServerStats,
        ParticipantHello,
    )
}


# ---- envelope ------------------------------------------------------------------------------------------------


def encode(sender: int, message: Any) -> bytes:
    """The payload for `message` from instance `sender` (a non-zero u64)."""
    if not 0 < sender < 1 << 64:
        raise ValueError("the sender must be a non-zero u64")
    out = bytearray(struct.pack("<HBQ", PROTOCOL_VERSION, message.KIND, sender))
    _write(type(message), message, out)
    return bytes(out)


def decode(payload: bytes, expected: Any = None):
    """(sender, message) of a payload; `expected` (a message class) refuses any other kind. Raises DecodeError."""
    payload = bytes(payload)
    if len(payload) < HEADER_LEN:
        raise DecodeError(f"truncated payload ({len(payload)} bytes, the header needs {HEADER_LEN})")
    version, kind, sender = struct.unpack("<HBQ", payload[:HEADER_LEN])
    if version != PROTOCOL_VERSION:
        raise DecodeError(f"protocol version {version}, this client speaks {PROTOCOL_VERSION}")
    cls = MESSAGES.get(kind)
    if cls is None:
        raise DecodeError(f"unknown message kind {kind}")
    if expected is not None and cls is not expected:
        raise DecodeError(f"a {cls.__name__} where a {expected.__name__} was expected")
    if sender == 0:
        raise DecodeError("sender 0")
    reader = _Reader(payload, HEADER_LEN)
    message = _read(cls, reader)
    if reader.at != len(payload):
        raise DecodeError(f"{len(payload) - reader.at} bytes left over after the body")
    return sender, message


def message_fields(message: Any) -> List[str]:
    """The field names of a message, in wire order."""
    return [f.name for f in fields(message)]
