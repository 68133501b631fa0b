"""The envelope and the postcard bodies of Sinew's messages (protocol 6), in pure Python.

Layout (protocol/WIRE.md): `[version u16 LE][kind u8][sender u64 LE][postcard body]`. Postcard writes unsigned
integers wider than a byte as LEB128 varints, floats as little-endian IEEE 754, bools as one byte, strings and
vectors as a varint length then the items, fixed arrays as their items, options and enums as a varint tag then
the value, structs as their fields in order. Each message is a dataclass whose fields, in declaration order,
carry their wire type (`wire_field`).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field, fields
from typing import Any, List, Optional

PROTOCOL_VERSION = 18
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
        for name, ft in _wire_fields(t):
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
    return t(**{name: _read(ft, r) for name, ft in _wire_fields(t)})


def wire_field(wire_type: Any, **kwargs: Any) -> Any:
    """A dataclass field with its wire type: a message's fields are written in declaration order."""
    return field(metadata={"wire": wire_type}, **kwargs)


def _wire_fields(cls: Any) -> List[tuple]:
    return [(f.name, f.metadata["wire"]) for f in fields(cls)]


V3 = ("arr", "f32", 3)
Q4 = ("arr", "f32", 4)
SYM3 = ("arr", "f32", 6)

# ---- messages ------------------------------------------------------------------------------------------------


@dataclass
class DevicePose:
    """Hapticserver -> server, 1 kHz, on sinew/<scene>/device/<id>/pose. Device frame, mm, mm/s, rad."""

    KIND = KIND_DEVICE_POSE
    seq: int = wire_field("u64", default=0)
    device_time_ns: int = wire_field("u64", default=0)
    position_mm: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    orientation_xyzw: List[float] = wire_field(Q4, default_factory=lambda: [0.0, 0.0, 0.0, 1.0])
    linear_velocity_mm_s: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    buttons: int = wire_field("u32", default=0)
    jaw_angle_rad: float = wire_field("f32", default=0.0)
    round_trip_us: int = wire_field("u32", default=0)
    render_mode: int = wire_field("u32", default=RENDER_DIRECT)  # enum RenderMode: its tag is a varint


@dataclass
class ContactPlane:
    """A unilateral plane of the local model: pushes out along `normal` below `offset_mm`."""

    normal: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    offset_mm: float = wire_field("f32", default=0.0)
    stiffness_n_per_mm: float = wire_field("f32", default=0.0)
    damping_n_s_per_mm: float = wire_field("f32", default=0.0)


@dataclass
class PunctureTerm:
    """A needle's tip pressing a surface (v16): the device pops it when its push back along the tip passes
    `pop_at_n`, then renders the model with the `*_after` terms. `press` 0: no term."""

    press: int = wire_field("u32", default=0)
    pop_at_n: float = wire_field("f32", default=0.0)
    tip_axis: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    f0_after_n: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    stiffness_after_n_per_mm: List[float] = wire_field(SYM3, default_factory=lambda: [0.0] * 6)
    drag_after_n: float = wire_field("f32", default=0.0)
    # The tip less the tool's origin and the tool's orientation when the model was built: the device pops on
    # its own turn too (v17).
    tip_lever_mm: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    orientation_xyzw: List[float] = wire_field(Q4, default_factory=lambda: [0.0, 0.0, 0.0, 0.0])


@dataclass
class LocalModel:
    """The tissue near the tool: f = f0 - K (x - x0) - D v within the radius, plus planes (WIRE.md)."""

    server_time_ns: int = wire_field("u64", default=0)
    in_contact: bool = wire_field("bool", default=False)
    x0_mm: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    f0_n: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    stiffness_n_per_mm: List[float] = wire_field(SYM3, default_factory=lambda: [0.0] * 6)
    damping_n_s_per_mm: List[float] = wire_field(SYM3, default_factory=lambda: [0.0] * 6)
    radius_mm: float = wire_field("f32", default=0.0)
    fade_mm: float = wire_field("f32", default=0.0)
    planes: List[ContactPlane] = wire_field(("arr", ContactPlane, 4), default_factory=lambda: [ContactPlane() for _ in range(4)])
    plane_count: int = wire_field("u8", default=0)
    energy_allowance_mj: float = wire_field("f32", default=0.0)
    # The tool holds tissue (a grasp): the linear part pulls both ways (v10).
    attached: bool = wire_field("bool", default=False)
    # The drag of cutting against the device's motion while a blade cuts, N (v10).
    cut_drag_n: float = wire_field("f32", default=0.0)
    # Coulomb friction the device renders about its own stick point: the cone and the stick spring (v11).
    friction_coefficient: float = wire_field("f32", default=0.0)
    stick_stiffness_n_per_mm: float = wire_field("f32", default=0.0)
    # How far the blade's edge travels between the facets it cuts, mm: the drag's sawtooth (v12).
    cut_facet_mm: float = wire_field("f32", default=0.0)
    # A needle's tip pressing a surface: the pop the device makes itself (v16).
    puncture: PunctureTerm = wire_field(PunctureTerm, default_factory=PunctureTerm)


@dataclass
class ForceCommand:
    """Server -> hapticserver on sinew/<scene>/device/<id>/force. `local_model` None is ForceMode::Direct."""

    KIND = KIND_FORCE_COMMAND
    seq: int = wire_field("u64", default=0)
    echo_pose_seq: int = wire_field("u64", default=0)
    echo_device_time_ns: int = wire_field("u64", default=0)
    force_n: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    # enum ForceMode { Direct = 0, LocalModel(LocalModel) = 1 }: the same bytes as an option.
    local_model: Optional[LocalModel] = wire_field(("opt", LocalModel), default=None)
    in_contact: bool = wire_field("bool", default=False)
    device_instance: int = wire_field("u64", default=0)
    # Microseconds the answered pose waited at the server before the tick that used it; None if not measured.
    pose_wait_us: Optional[int] = wire_field(("opt", "u32"), default=None)


@dataclass
class ParticipantHello:
    """Any participant -> everyone on sinew/<scene>/hello/<role>/<id>, on start and every second."""

    KIND = KIND_PARTICIPANT_HELLO
    participant_id: str = wire_field("str", default="")
    role: int = wire_field("u32", default=ROLE_HAPTIC)  # enum Role: 0 Server, 1 Haptic, 2 Viewer
    device_model: str = wire_field("str", default="")
    max_force_n: float = wire_field("f32", default=0.0)
    tool: str = wire_field("str", default="")


@dataclass
class TopologyDelta:
    """A cut or tear: vertices split off their parents, triangles re-pointed, surface triangles added (ids are
    only ever appended; a re-pointed triangle keeps its id). Apply before the delta's positions and burn."""

    epoch: int = wire_field("u32", default=0)
    first_vertex: int = wire_field("u32", default=0)
    parents: List[int] = wire_field(("vec", "u32"), default_factory=list)
    retargeted: List[int] = wire_field(("vec", "u32"), default_factory=list)
    corners: List[List[int]] = wire_field(("vec", ("arr", "u32", 3)), default_factory=list)
    first_triangle: int = wire_field("u32", default=0)
    added: List[List[int]] = wire_field(("vec", ("arr", "u32", 3)), default_factory=list)


@dataclass
class MeshDelta:
    """Server -> viewers: the changed vertices of one object, quantized against its snapshot bounds."""

    KIND = KIND_MESH_DELTA
    object: int = wire_field("u16", default=0)
    frame: int = wire_field("u64", default=0)
    prev_frame: int = wire_field("u64", default=0)
    indices: List[int] = wire_field(("vec", "u32"), default_factory=list)
    positions_q: List[List[int]] = wire_field(("vec", ("arr", "u16", 3)), default_factory=list)
    burn_indices: List[int] = wire_field(("vec", "u32"), default_factory=list)
    burn: List[int] = wire_field(("vec", "u8"), default_factory=list)
    topology: Optional[TopologyDelta] = wire_field(("opt", TopologyDelta), default=None)


@dataclass
class ToolState:
    """One tool, world frame: position, orientation, the tissue's force on it."""

    tool: int = wire_field("u16", default=0)
    position_mm: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    orientation_xyzw: List[float] = wire_field(Q4, default_factory=lambda: [0.0, 0.0, 0.0, 1.0])
    force_n: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    active: bool = wire_field("bool", default=False)
    in_contact: bool = wire_field("bool", default=False)
    jaw_angle_rad: float = wire_field("f32", default=0.0)
    attachments: int = wire_field("u16", default=0)


@dataclass
class QuantBounds:
    min_mm: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    max_mm: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])

    def dequantize(self, q: List[int]) -> List[float]:
        return [self.min_mm[a] + q[a] / 65535.0 * (self.max_mm[a] - self.min_mm[a]) for a in range(3)]


@dataclass
class HoleMark:
    """A puncture in a tissue's surface made by a thread's needle: where it is, how hard it pulls (protocol 18)."""

    position_mm: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    pull_n: float = wire_field("f32", default=0.0)
    on_needle: bool = wire_field("bool", default=False)


@dataclass
class ThreadState:
    """A suture thread as it lies: its polyline in the world, mm, from the needle's tail (protocol 14)."""

    tool: int = wire_field("u16", default=0)
    bounds: QuantBounds = wire_field(QuantBounds, default_factory=lambda: QuantBounds([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]))
    nodes_q: List[List[int]] = wire_field(("vec", ("arr", "u16", 3)), default_factory=list)
    holes: List[HoleMark] = wire_field(("vec", HoleMark), default_factory=list)

    def nodes_mm(self) -> List[List[float]]:
        return [self.bounds.dequantize(q) for q in self.nodes_q]


@dataclass
class NeedleState:
    """Where a needle driver's needle lies, whoever holds it: the pose its driver's jaws would hold it at (protocol 15)."""

    tool: int = wire_field("u16", default=0)
    position_mm: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    orientation_xyzw: List[float] = wire_field(Q4, default_factory=lambda: [0.0, 0.0, 0.0, 1.0])


@dataclass
class ToolStates:
    """Server -> viewers on sinew/<scene>/tools, every publish frame."""

    KIND = KIND_TOOL_STATES
    frame: int = wire_field("u64", default=0)
    sim_time_s: float = wire_field("f64", default=0.0)
    tools: List[ToolState] = wire_field(("vec", ToolState), default_factory=list)
    threads: List[ThreadState] = wire_field(("vec", ThreadState), default_factory=list)
    needles: List[NeedleState] = wire_field(("vec", NeedleState), default_factory=list)


@dataclass
class ObjectSnapshot:
    object: int = wire_field("u16", default=0)
    name: str = wire_field("str", default="")
    bounds: QuantBounds = wire_field(QuantBounds, default_factory=QuantBounds)
    triangles: List[List[int]] = wire_field(("vec", ("arr", "u32", 3)), default_factory=list)
    positions_q: List[List[int]] = wire_field(("vec", ("arr", "u16", 3)), default_factory=list)
    frame: int = wire_field("u64", default=0)
    burn: List[int] = wire_field(("vec", "u8"), default_factory=list)
    topology_epoch: int = wire_field("u32", default=0)
    error_bound_mm: float = wire_field("f32", default=0.0)


TOOL_SHAPE = (
    "variants",
    [
        ("sphere", [("radius_mm", "f32")]),
        ("capsule", [("half_length_mm", "f32"), ("radius_mm", "f32")]),
        ("mesh", [("positions_mm", ("vec", V3)), ("triangles", ("vec", ("arr", "u32", 3)))]),
    ],
)

INSTRUMENT = (
    "variants",
    [
        ("probe", []),
        ("grasper", [("jaw_length_mm", "f32"), ("open_angle_rad", "f32")]),
        ("cautery", []),
        ("scalpel", [("edge_from_mm", V3), ("edge_to_mm", V3)]),
        ("scissors", [("hinge_mm", V3), ("blade_length_mm", "f32"), ("open_angle_rad", "f32")]),
        (
            "needle_driver",
            [
                ("jaw_length_mm", "f32"),
                ("needle_radius_mm", "f32"),
                ("needle_sweep_rad", "f32"),
                ("needle_diameter_mm", "f32"),
                ("grasp_at_rad", "f32"),
            ],
        ),
    ],
)


@dataclass
class ToolShaft:
    radius_mm: float = wire_field("f32", default=0.0)
    length_mm: float = wire_field("f32", default=0.0)


@dataclass
class ToolInfo:
    tool: int = wire_field("u16", default=0)
    name: str = wire_field("str", default="")
    device_id: str = wire_field("str", default="")
    shape: dict = wire_field(TOOL_SHAPE, default_factory=lambda: {"kind": "sphere", "radius_mm": 1.0})
    instrument: dict = wire_field(INSTRUMENT, default_factory=lambda: {"kind": "probe"})
    shaft: Optional[ToolShaft] = wire_field(("opt", ToolShaft), default=None)


@dataclass
class SceneSnapshot:
    """Server -> querier: the reply to a query on sinew/<scene>/snapshot."""

    KIND = KIND_SCENE_SNAPSHOT
    scene: str = wire_field("str", default="")
    frame: int = wire_field("u64", default=0)
    objects: List[ObjectSnapshot] = wire_field(("vec", ObjectSnapshot), default_factory=list)
    tools: List[ToolInfo] = wire_field(("vec", ToolInfo), default_factory=list)
    tool_states: ToolStates = wire_field(ToolStates, default_factory=ToolStates)


@dataclass
class RejectCounts:
    malformed: int = wire_field("u64", default=0)
    wrong_version: int = wire_field("u64", default=0)
    invalid: int = wire_field("u64", default=0)
    unknown_device: int = wire_field("u64", default=0)
    duplicate_device: int = wire_field("u64", default=0)
    wrong_tool: int = wire_field("u64", default=0)
    no_hello: int = wire_field("u64", default=0)
    access_denied: int = wire_field("u64", default=0)
    tls_refused: int = wire_field("u64", default=0)


@dataclass
class TrainingStats:
    skill_state: str = wire_field("str", default="")
    contacts: int = wire_field("u64", default=0)
    contact_time_s: float = wire_field("f32", default=0.0)
    path_length_mm: float = wire_field("f32", default=0.0)
    peak_force_n: float = wire_field("f32", default=0.0)
    harm_n_s: float = wire_field("f32", default=0.0)


@dataclass
class DeviceStats:
    device_id: str = wire_field("str", default="")
    active: bool = wire_field("bool", default=False)
    poses_received: int = wire_field("u64", default=0)
    forces_sent: int = wire_field("u64", default=0)
    last_round_trip_us: int = wire_field("u32", default=0)
    max_force_n: float = wire_field("f32", default=0.0)
    moderated: bool = wire_field("bool", default=False)
    forces_suppressed: int = wire_field("u64", default=0)
    tool: str = wire_field("str", default="")
    holder_instance: int = wire_field("u64", default=0)
    duplicates_refused: int = wire_field("u64", default=0)
    last_refused_instance: int = wire_field("u64", default=0)
    wrong_tool_instance: int = wire_field("u64", default=0)
    wrong_tool_asked: str = wire_field("str", default="")
    force_limit_n: float = wire_field("f32", default=0.0)
    training: TrainingStats = wire_field(TrainingStats, default_factory=TrainingStats)


@dataclass
class TargetMark:
    """One target of the running exercise: where it is marked, its radius, hit or not (protocol 18)."""

    at_mm: List[float] = wire_field(V3, default_factory=lambda: [0.0, 0.0, 0.0])
    radius_mm: float = wire_field("f32", default=0.0)
    hit: bool = wire_field("bool", default=False)


@dataclass
class ExerciseStats:
    kind: str = wire_field("str", default="")
    score: float = wire_field("f32", default=0.0)
    hits: int = wire_field("u32", default=0)
    total: int = wire_field("u32", default=0)
    errors: int = wire_field("u32", default=0)
    time_s: float = wire_field("f32", default=0.0)
    completed: bool = wire_field("bool", default=False)
    timed_out: bool = wire_field("bool", default=False)
    targets: List[TargetMark] = wire_field(("vec", TargetMark), default_factory=list)


@dataclass
class ServerStats:
    """Server -> anyone on sinew/<scene>/stats, once a second."""

    KIND = KIND_SERVER_STATS
    sim_time_s: float = wire_field("f64", default=0.0)
    ticks: int = wire_field("u64", default=0)
    tick_p50_us: float = wire_field("f32", default=0.0)
    tick_p99_us: float = wire_field("f32", default=0.0)
    tick_max_us: float = wire_field("f32", default=0.0)
    overruns: int = wire_field("u64", default=0)
    sim_faults: int = wire_field("u64", default=0)
    deltas_sent: int = wire_field("u64", default=0)
    delta_bytes_sent: int = wire_field("u64", default=0)
    snapshots_served: int = wire_field("u64", default=0)
    quantization_clamps: int = wire_field("u64", default=0)
    rejected: RejectCounts = wire_field(RejectCounts, default_factory=RejectCounts)
    devices: List[DeviceStats] = wire_field(("vec", DeviceStats), default_factory=list)
    server_id: str = wire_field("str", default="")
    foreign_server_messages: int = wire_field("u64", default=0)
    foreign_server_instance: int = wire_field("u64", default=0)
    exercise: Optional[ExerciseStats] = wire_field(("opt", ExerciseStats), default=None)


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

