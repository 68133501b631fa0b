//! The recording's layout: the file with its `sinew` metadata, and its channels and schemas.
//!
//! Owns: creating the MCAP file ([`open_file`]) and adding the fixed channels, with one pose and one force
//! channel per tool ([`Channels::add`]). Must not: write messages (the writer thread does) or run on the
//! sim thread.

use super::*;
use crate::recording::{
    FORMAT_VERSION, TICKS_ENCODING, TOPIC_EVENTS, TOPIC_FINAL, TOPIC_PRESENCE, TOPIC_STATS,
    TOPIC_TICKS, TOPIC_TOOLS,
};

/// Create the file and write its `sinew` metadata (format, protocol, scene, and `extra`).
pub(super) fn open_file(
    path: &Path,
    scene: &str,
    extra: BTreeMap<String, String>,
) -> Result<mcap::Writer<BufWriter<File>>, RecordError> {
    let file = File::create(path).map_err(|e| RecordError::Create {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    let mut out = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        // Compress on this thread: helper threads would compete with the 1 kHz loops for the cores.
        .compression_threads(0)
        .profile("sinew")
        .create(BufWriter::new(file))
        .map_err(write_error(path))?;
    let mut metadata = extra;
    metadata.insert("format_version".to_owned(), FORMAT_VERSION.to_string());
    metadata.insert(
        "protocol_version".to_owned(),
        sinew_protocol::PROTOCOL_VERSION.to_string(),
    );
    metadata.insert("scene".to_owned(), scene.to_owned());
    out.write_metadata(&mcap::records::Metadata {
        name: "sinew".to_owned(),
        metadata,
    })
    .map_err(write_error(path))?;
    Ok(out)
}

impl Channels {
    pub(super) fn add<W: std::io::Write + std::io::Seek>(
        out: &mut mcap::Writer<W>,
        world: Option<&World>,
    ) -> Result<Self, mcap::McapError> {
        let none = BTreeMap::new();
        let ticks = out.add_channel(0, TOPIC_TICKS, TICKS_ENCODING, &none)?;
        let final_state = out.add_channel(0, TOPIC_FINAL, TICKS_ENCODING, &none)?;
        let pose_schema = out.add_schema(
            "sinew.DevicePose",
            "jsonschema",
            crate::recording::json_view::POSE_SCHEMA.as_bytes(),
        )?;
        let force_schema = out.add_schema(
            "sinew.ForceCommand",
            "jsonschema",
            crate::recording::json_view::FORCE_SCHEMA.as_bytes(),
        )?;
        let event_schema = out.add_schema(
            "sinew.SessionEvent",
            "jsonschema",
            crate::recording::json_view::EVENT_SCHEMA.as_bytes(),
        )?;
        let events = out.add_channel(event_schema, TOPIC_EVENTS, "json", &none)?;
        let mut json_channel = |name: &str, schema: &str, topic: &str| {
            let schema = out.add_schema(name, "jsonschema", schema.as_bytes())?;
            out.add_channel(schema, topic, "json", &none)
        };
        let tools_json = json_channel(
            "sinew.ToolStates",
            crate::recording::json_view::TOOLS_SCHEMA,
            TOPIC_TOOLS,
        )?;
        let stats_json = json_channel(
            "sinew.ServerStats",
            crate::recording::json_view::STATS_SCHEMA,
            TOPIC_STATS,
        )?;
        let presence_json = json_channel(
            "sinew.Presence",
            crate::recording::json_view::PRESENCE_SCHEMA,
            TOPIC_PRESENCE,
        )?;
        let tools = world.map_or(&[][..], |w| &w.tools[..]);
        let mut devices = Vec::with_capacity(tools.len());
        for tool in tools {
            let mut metadata = BTreeMap::new();
            metadata.insert("tool".to_owned(), tool.name.clone());
            let pose = out.add_channel(
                pose_schema,
                &format!("/sinew/{}/pose", tool.device_id),
                "json",
                &metadata,
            )?;
            let force = out.add_channel(
                force_schema,
                &format!("/sinew/{}/force", tool.device_id),
                "json",
                &metadata,
            )?;
            devices.push((pose, force));
        }
        Ok(Self {
            ticks,
            final_state,
            events,
            tools_json,
            stats_json,
            presence_json,
            wire: BTreeMap::new(),
            device_ids: tools.iter().map(|t| t.device_id.clone()).collect(),
            devices,
        })
    }
}
