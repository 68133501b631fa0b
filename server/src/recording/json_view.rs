//! The JSON view of a recording's poses and forces, with the JSON schemas Foxglove reads them by. A view only:
//! replay reads the exact postcard channel, never these.

use serde_json::json;
use sinew_protocol::{DevicePose, ForceCommand, ForceMode, RenderMode};

/// JSON schema of `/sinew/<device>/pose`.
pub const POSE_SCHEMA: &str = r#"{
  "title": "sinew.DevicePose",
  "description": "A device pose as the server tick used it (device frame, mm).",
  "type": "object",
  "properties": {
    "seq": {"type": "integer", "description": "pose sequence number"},
    "device_time_ns": {"type": "integer", "description": "device clock when sampled, ns"},
    "position_mm": {"type": "array", "items": {"type": "number"}, "description": "stylus position x y z, mm"},
    "orientation_xyzw": {"type": "array", "items": {"type": "number"}, "description": "stylus orientation quaternion"},
    "linear_velocity_mm_s": {"type": "array", "items": {"type": "number"}, "description": "stylus velocity, mm/s"},
    "buttons": {"type": "integer", "description": "button bits"},
    "jaw_angle_rad": {"type": "number", "description": "jaw or activation angle, rad"},
    "round_trip_us": {"type": "integer", "description": "the device's last measured round trip, us"},
    "render_mode": {"type": "string", "enum": ["direct", "moderated"]},
    "age_s": {"type": "number", "description": "age of the pose when the tick read it, s"},
    "usable": {"type": "boolean", "description": "the device could drive its tool"}
  }
}"#;

/// JSON schema of `/sinew/<device>/force`.
pub const FORCE_SCHEMA: &str = r#"{
  "title": "sinew.ForceCommand",
  "description": "A force command the server sent a device (device frame, N).",
  "type": "object",
  "properties": {
    "seq": {"type": "integer"},
    "echo_pose_seq": {"type": "integer", "description": "the pose this answers"},
    "force_n": {"type": "array", "items": {"type": "number"}, "description": "force x y z, N"},
    "force_magnitude_n": {"type": "number", "description": "|force|, N"},
    "in_contact": {"type": "boolean"},
    "mode": {"type": "string", "enum": ["direct", "local_model"]}
  }
}"#;

/// JSON schema of `/sinew/events`.
pub const EVENT_SCHEMA: &str = r#"{
  "title": "sinew.SessionEvent",
  "description": "A training event: an edge of a tool's activity (contact, grasp, cut, burn, harm, fault).",
  "type": "object",
  "properties": {
    "tick": {"type": "integer", "description": "server tick"},
    "tool": {"type": "integer", "description": "tool index in the world"},
    "device": {"type": "string", "description": "the device bound to the tool"},
    "kind": {"type": "string", "description": "joined, left, approach_begin, contact_begin, grasp_begin, harm_begin, tissue_fault, ..."}
  }
}"#;

/// A training event as JSON.
pub fn event_json(event: &crate::training::SessionEvent, device: &str) -> Result<String, String> {
    serde_json::to_string(&json!({
        "tick": event.tick,
        "tool": event.tool,
        "device": device,
        "kind": event.kind.name(),
    }))
    .map_err(|e| e.to_string())
}

/// A pose as JSON.
pub fn pose_json(pose: &DevicePose, age_s: f64, usable: bool) -> Result<String, String> {
    serde_json::to_string(&json!({
        "seq": pose.seq,
        "device_time_ns": pose.device_time_ns,
        "position_mm": pose.position_mm,
        "orientation_xyzw": pose.orientation_xyzw,
        "linear_velocity_mm_s": pose.linear_velocity_mm_s,
        "buttons": pose.buttons,
        "jaw_angle_rad": pose.jaw_angle_rad,
        "round_trip_us": pose.round_trip_us,
        "render_mode": match pose.render_mode {
            RenderMode::Direct => "direct",
            RenderMode::Moderated => "moderated",
        },
        "age_s": age_s,
        "usable": usable,
    }))
    .map_err(|e| e.to_string())
}

/// A force command as JSON.
pub fn force_json(force: &ForceCommand) -> Result<String, String> {
    let [x, y, z] = force.force_n;
    serde_json::to_string(&json!({
        "seq": force.seq,
        "echo_pose_seq": force.echo_pose_seq,
        "force_n": force.force_n,
        "force_magnitude_n": (x * x + y * y + z * z).sqrt(),
        "in_contact": force.in_contact,
        "mode": match force.mode {
            ForceMode::Direct => "direct",
            ForceMode::LocalModel(_) => "local_model",
        },
    }))
    .map_err(|e| e.to_string())
}

/// JSON schema of `/sinew/tools` (the serde form of [`sinew_protocol::ToolStates`]).
pub const TOOLS_SCHEMA: &str = r#"{
  "title": "sinew.ToolStates",
  "description": "Every tool's pose and the force the tissue exerts on it, as published to viewers (world frame, mm, N).",
  "type": "object",
  "properties": {
    "frame": {"type": "integer", "description": "publish frame"},
    "sim_time_s": {"type": "number", "description": "simulated time, s"},
    "tools": {"type": "array", "items": {"type": "object", "properties": {
      "tool": {"type": "integer"},
      "position_mm": {"type": "array", "items": {"type": "number"}},
      "orientation_xyzw": {"type": "array", "items": {"type": "number"}},
      "force_n": {"type": "array", "items": {"type": "number"}},
      "active": {"type": "boolean"},
      "in_contact": {"type": "boolean"}
    }}}
  }
}"#;

/// JSON schema of `/sinew/stats` (the serde form of [`sinew_protocol::ServerStats`]).
pub const STATS_SCHEMA: &str = r#"{
  "title": "sinew.ServerStats",
  "description": "Server health at 1 Hz: tick time, per device its round trip (last_round_trip_us), mode, force limit and training view; the exercise's live score.",
  "type": "object"
}"#;

/// JSON schema of `/sinew/presence`.
pub const PRESENCE_SCHEMA: &str = r#"{
  "title": "sinew.Presence",
  "description": "A participant's presence token appeared (joined) or went away.",
  "type": "object",
  "properties": {
    "key": {"type": "string"},
    "role": {"type": "string", "description": "server, haptic or viewer"},
    "id": {"type": "string"},
    "joined": {"type": "boolean"}
  }
}"#;

/// A presence change as JSON: the key `sinew/<scene>/presence/<role>/<id>` split into role and id.
pub fn presence_json(key: &str, joined: bool) -> Result<String, String> {
    let mut tail = key.rsplit('/');
    let id = tail.next().unwrap_or_default();
    let role = tail.next().unwrap_or_default();
    serde_json::to_string(&json!({
        "key": key,
        "role": role,
        "id": id,
        "joined": joined,
    }))
    .map_err(|e| e.to_string())
}
