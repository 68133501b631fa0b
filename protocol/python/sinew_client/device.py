"""A haptic device client over zenoh, keeping the rules of protocol/WIRE.md ("Rules a device keeps").

    device = Device("pad", "left", connect=["tcp/127.0.0.1:7447"], max_force_n=3.3)
    device.open()
    while running:
        device.publish_pose(position_mm)       # 1 kHz, device frame
        force = device.latest_force()          # the newest admitted ForceCommand, or None
    device.close()

It joins (presence token, then a hello every second), publishes poses with its monotonic clock, admits only
force commands addressed to its own instance from the server instance it joined, and measures the round trip
from the first command that echoes each newer pose. Rendering and device-side safety (clamp, rate limit, ramp
to zero on silence) belong to the driver that calls it: `safe_force` gives the clamp and the silence rule.
"""

from __future__ import annotations

import json
import random
import threading
import time
from typing import List, Optional

import zenoh

from . import wire

#: A joined server silent this long may be replaced by the next one heard, s (WIRE.md).
QUIET_SWITCH_S = 0.3
#: A command older than this is stale, s; the force then falls to zero (WIRE.md, device safety).
STALE_AFTER_S = 0.050


def session_config(connect: List[str]) -> "zenoh.Config":
    """Sinew's client defaults: peer mode, connect only, no multicast scouting, fast reconnects."""
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("connect/endpoints", json.dumps(connect))
    config.insert_json5("listen/endpoints", "[]")
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/gossip/autoconnect", '{router: [], peer: ["router"]}')
    return config


class Device:
    """One device's participation in a scene."""

    def __init__(
        self,
        scene: str,
        device_id: str,
        connect: Optional[List[str]] = None,
        max_force_n: float = 3.3,
        tool: str = "",
        device_model: str = "python",
    ):
        self.scene = scene
        self.device_id = device_id
        self.connect = connect or ["tcp/127.0.0.1:7447"]
        self.max_force_n = max_force_n
        self.tool = tool
        self.device_model = device_model
        self.instance = random.getrandbits(64) or 1
        self.render_mode = wire.RENDER_DIRECT
        self._t0_ns = time.monotonic_ns()
        self._seq = 0
        self._lock = threading.Lock()
        self._latest: Optional[wire.ForceCommand] = None
        self._latest_at = 0.0
        self._joined_server = 0
        self._joined_heard = 0.0
        self._last_echo_seq = 0
        self.round_trip_us = 0
        self.refused = {"not_ours": 0, "other_server": 0, "malformed": 0}
        self._stop = threading.Event()
        self._session = None

    def key(self, tail: str) -> str:
        return f"sinew/{self.scene}/{tail}"

    def open(self) -> None:
        """Open zenoh, declare presence and the force subscriber, say hello (and keep saying it every second)."""
        self._session = zenoh.open(session_config(self.connect))
        self._token = self._session.liveliness().declare_token(self.key(f"presence/haptic/{self.device_id}"))
        self._forces = self._session.declare_subscriber(
            self.key(f"device/{self.device_id}/force"), self._on_force
        )
        self._poses = self._session.declare_publisher(
            self.key(f"device/{self.device_id}/pose"),
            congestion_control=zenoh.CongestionControl.DROP,
            express=True,
        )
        self._hello = self._session.declare_publisher(self.key(f"hello/haptic/{self.device_id}"))
        self._say_hello()
        self._hello_thread = threading.Thread(target=self._hello_loop, name="sinew-hello", daemon=True)
        self._hello_thread.start()

    def _say_hello(self) -> None:
        hello = wire.ParticipantHello(
            participant_id=self.device_id,
            role=wire.ROLE_HAPTIC,
            device_model=self.device_model,
            max_force_n=self.max_force_n,
            tool=self.tool,
        )
        self._hello.put(wire.encode(self.instance, hello))

    def _hello_loop(self) -> None:
        while not self._stop.wait(1.0):
            self._say_hello()

    def now_ns(self) -> int:
        """The device clock: ns since this client started."""
        return time.monotonic_ns() - self._t0_ns

    def publish_pose(
        self,
        position_mm,
        velocity_mm_s=(0.0, 0.0, 0.0),
        orientation_xyzw=(0.0, 0.0, 0.0, 1.0),
        buttons: int = 0,
        jaw_angle_rad: float = 0.0,
    ) -> int:
        """Publish one pose (device frame, mm); returns its sequence number."""
        self._seq += 1
        pose = wire.DevicePose(
            seq=self._seq,
            device_time_ns=self.now_ns(),
            position_mm=list(position_mm),
            orientation_xyzw=list(orientation_xyzw),
            linear_velocity_mm_s=list(velocity_mm_s),
            buttons=buttons,
            jaw_angle_rad=jaw_angle_rad,
            round_trip_us=self.round_trip_us,
            render_mode=self.render_mode,
        )
        self._poses.put(wire.encode(self.instance, pose))
        return self._seq

    def _on_force(self, sample) -> None:
        try:
            sender, command = wire.decode(sample.payload.to_bytes(), wire.ForceCommand)
        except wire.DecodeError:
            self.refused["malformed"] += 1
            return
        if command.device_instance != self.instance:
            # Meant for another hapticserver using this id (the server refused one of us).
            self.refused["not_ours"] += 1
            return
        now = time.monotonic()
        with self._lock:
            quiet = now - self._joined_heard > QUIET_SWITCH_S
            if self._joined_server not in (0, sender) and not quiet:
                self.refused["other_server"] += 1
                return
            self._joined_server = sender
            self._joined_heard = now
            if command.echo_pose_seq > self._last_echo_seq and command.echo_pose_seq <= self._seq:
                self._last_echo_seq = command.echo_pose_seq
                rt_ns = self.now_ns() - command.echo_device_time_ns
                self.round_trip_us = max(0, min(rt_ns // 1000, 2**32 - 1))
            self._latest = command
            self._latest_at = now

    def latest_force(self) -> Optional[wire.ForceCommand]:
        """The newest admitted command, or None before the first."""
        with self._lock:
            return self._latest

    def safe_force(self) -> List[float]:
        """The force to render now under the wire's two simplest rules: zero when the newest command is stale
        (a driver should ramp it over 20 ms and limit its rate), and clamped to the device maximum."""
        with self._lock:
            command, at = self._latest, self._latest_at
        if command is None or time.monotonic() - at > STALE_AFTER_S:
            return [0.0, 0.0, 0.0]
        f = command.force_n
        if not all(map(lambda c: c == c and abs(c) != float("inf"), f)):
            return [0.0, 0.0, 0.0]
        norm = sum(c * c for c in f) ** 0.5
        scale = min(1.0, self.max_force_n / norm) if norm > 0 else 1.0
        return [c * scale for c in f]

    def close(self) -> None:
        """Leave: the token goes (the server releases the tool at once), then the session."""
        self._stop.set()
        if self._session is not None:
            self._token.undeclare()
            self._session.close()
            self._session = None
