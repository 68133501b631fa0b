"""Sinew's wire in Python (protocol 18; the specification is protocol/WIRE.md).

- `sinew_client.wire`: the envelope and postcard codec of every message (pure Python, no zenoh).
- `sinew_client.device`: a haptic device client over zenoh: join (token, hello), publish poses, receive forces,
  measure the round trip as the wire's rules say.
"""

from .wire import (
    PROTOCOL_VERSION,
    DecodeError,
    DevicePose,
    ForceCommand,
    LocalModel,
    ContactPlane,
    PunctureTerm,
    ParticipantHello,
    MeshDelta,
    NeedleState,
    HoleMark,
    ThreadState,
    ToolState,
    ToolStates,
    SceneSnapshot,
    ServerStats,
    ExerciseStats,
    TargetMark,
    decode,
    encode,
)

__all__ = [
    "PROTOCOL_VERSION",
    "DecodeError",
    "DevicePose",
    "ForceCommand",
    "LocalModel",
    "ContactPlane",
    "PunctureTerm",
    "ParticipantHello",
    "MeshDelta",
    "NeedleState",
    "HoleMark",
    "ThreadState",
    "ToolState",
    "ToolStates",
    "SceneSnapshot",
    "ServerStats",
    "ExerciseStats",
    "TargetMark",
    "decode",
    "encode",
]
