//! Reading a recording back: its metadata, the world files it carries, every exact tick record and the final
//! state. A damaged or truncated file yields what precedes the damage, and says where it stopped.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use thiserror::Error;

use super::tick_record::{FinalState, TickMessage};
use super::world_files::is_plain_relative;
use super::{FORMAT_VERSION, TOPIC_EVENTS, TOPIC_FINAL, TOPIC_PRESENCE, TOPIC_TICKS};
use crate::world::{World, WorldError, load_world};

/// Why a recording cannot be read (nothing of it is usable).
#[derive(Debug, Error)]
pub enum ReadError {
    /// The file could not be read.
    #[error("`{path}`: {message}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        message: String,
    },
    /// Not an MCAP file, or not one Sinew wrote.
    #[error("`{path}` is not a Sinew recording: {message}")]
    NotARecording {
        /// The file.
        path: PathBuf,
        /// What is missing or wrong.
        message: String,
    },
    /// Written by another version of the recording layout or the protocol.
    #[error("`{path}` was recorded with {what} {found}; this build reads {expected}")]
    Version {
        /// The file.
        path: PathBuf,
        /// Which version.
        what: &'static str,
        /// In the file.
        found: String,
        /// This build's.
        expected: String,
    },
    /// Written by `sinew-recorder`: what was published, not the tick inputs a replay needs.
    #[error(
        "`{path}` was written by sinew-recorder: it holds what the scene published (open it in Foxglove; `sinew \
         info` lists it), not the tick inputs a replay or a report needs; record with `sinew-server --record` or \
         `sinew demo --record` for those"
    )]
    WireOnly {
        /// The file.
        path: PathBuf,
    },
    /// The world it carries does not load.
    #[error("`{path}`: the world it carries does not load: {source}")]
    World {
        /// The recording.
        path: PathBuf,
        /// The loader's error.
        source: Box<WorldError>,
    },
}

/// A recording, read.
#[derive(Debug, Clone)]
pub struct Recording {
    /// The file.
    pub path: PathBuf,
    /// Its `sinew` metadata.
    pub metadata: BTreeMap<String, String>,
    /// The world's files, world file first: (name, contents).
    pub files: Vec<(String, Vec<u8>)>,
    /// Every tick record, in file order.
    pub ticks: Vec<TickMessage>,
    /// The tissue when the recording ended (None if the session did not end cleanly or the end is damaged).
    pub final_state: Option<FinalState>,
    /// Why reading stopped before the end, if it did (damage, truncation): the ticks before it are usable.
    pub damage: Option<String>,
    /// The training events the live session recorded, as (tick, tool, kind name), in file order.
    pub events: Vec<(u64, u8, String)>,
    /// Messages per topic, every channel (the exact ones, the views, and each zenoh key heard).
    pub topic_counts: BTreeMap<String, u64>,
    /// Participant presence changes heard, as (log time ns, presence key, joined), in file order.
    pub presence: Vec<(u64, String, bool)>,
}

impl Recording {
    /// The recording's kind: [`super::KIND_SESSION`] or [`super::KIND_WIRE`] (files from before kinds existed
    /// are sessions).
    pub fn kind(&self) -> &str {
        self.metadata
            .get("kind")
            .map_or(super::KIND_SESSION, String::as_str)
    }

    /// How many forces the recording holds: device-ticks with a force (each device's from the tick it joined),
    /// what a replay compares.
    pub fn recorded_forces(&self) -> u64 {
        self.ticks
            .iter()
            .flat_map(|t| &t.devices)
            .filter(|d| d.force.is_some())
            .count() as u64
    }
}

/// Read any Sinew recording, a session or `sinew-recorder`'s (which has no ticks and no world): its metadata,
/// what each topic holds and the presence changes. Errors as [`read_recording`] does, except for the world.
pub fn survey(path: &Path) -> Result<Recording, ReadError> {
    read_any(path)
}

/// Read `path`. Errors only when nothing of it is usable; damage after a usable start is in
/// [`Recording::damage`].
pub fn read_recording(path: &Path) -> Result<Recording, ReadError> {
    let recording = read_any(path)?;
    if recording.kind() == super::KIND_WIRE {
        return Err(ReadError::WireOnly {
            path: path.to_owned(),
        });
    }
    if recording.files.is_empty() {
        return Err(ReadError::NotARecording {
            path: path.to_owned(),
            message: "it carries no world file".to_owned(),
        });
    }
    Ok(recording)
}

fn read_any(path: &Path) -> Result<Recording, ReadError> {
    let bytes = std::fs::read(path).map_err(|e| ReadError::Read {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    let not_a_recording = |message: String| ReadError::NotARecording {
        path: path.to_owned(),
        message,
    };
    let mut records = Records::new(&bytes);
    let mut recording = Recording {
        path: path.to_owned(),
        metadata: BTreeMap::new(),
        files: Vec::new(),
        ticks: Vec::new(),
        final_state: None,
        damage: None,
        events: Vec::new(),
        topic_counts: BTreeMap::new(),
        presence: Vec::new(),
    };
    let mut topics: HashMap<u16, String> = HashMap::new();
    let mut seen_metadata = false;
    while let Some(record) = records.next() {
        let offset = records.offset();
        let record = match record {
            Ok(record) => record,
            Err(e) if seen_metadata => {
                recording.damage = Some(damage_at(&recording, offset, &e.to_string()));
                break;
            }
            Err(e) => return Err(not_a_recording(e.to_string())),
        };
        match record {
            mcap::records::Record::Metadata(metadata) if metadata.name == "sinew" => {
                check_versions(path, &metadata.metadata)?;
                recording.metadata = metadata.metadata;
                seen_metadata = true;
            }
            mcap::records::Record::Attachment { header, data, .. } => {
                recording.files.push((header.name, data.into_owned()));
            }
            mcap::records::Record::Channel(channel) => {
                topics.insert(channel.id, channel.topic);
            }
            mcap::records::Record::Message { header, data } => {
                if let Some(topic) = topics.get(&header.channel_id) {
                    *recording.topic_counts.entry(topic.clone()).or_default() += 1;
                }
                match topics.get(&header.channel_id).map(String::as_str) {
                    Some(TOPIC_TICKS) => match postcard::from_bytes::<TickMessage>(&data) {
                        Ok(tick) => recording.ticks.push(tick),
                        Err(e) => {
                            recording.damage = Some(damage_at(
                                &recording,
                                offset,
                                &format!("a tick record is corrupt ({e})"),
                            ));
                            break;
                        }
                    },
                    Some(TOPIC_EVENTS) => {
                        // A view: an unreadable one is skipped, never damage.
                        if let Ok(value) = serde_json::from_slice::<serde_json::Value>(&data)
                            && let (Some(tick), Some(tool), Some(kind)) = (
                                value["tick"].as_u64(),
                                value["tool"].as_u64(),
                                value["kind"].as_str(),
                            )
                        {
                            recording
                                .events
                                .push((tick, tool.min(255) as u8, kind.to_owned()));
                        }
                    }
                    Some(TOPIC_PRESENCE) => {
                        // A view: an unreadable one is skipped, never damage.
                        if let Ok(value) = serde_json::from_slice::<serde_json::Value>(&data)
                            && let (Some(key), Some(joined)) =
                                (value["key"].as_str(), value["joined"].as_bool())
                        {
                            recording
                                .presence
                                .push((header.log_time, key.to_owned(), joined));
                        }
                    }
                    Some(TOPIC_FINAL) => match postcard::from_bytes::<FinalState>(&data) {
                        Ok(state) => recording.final_state = Some(state),
                        Err(e) => {
                            recording.damage = Some(damage_at(
                                &recording,
                                offset,
                                &format!("the final state is corrupt ({e})"),
                            ));
                            break;
                        }
                    },
                    _ => {}
                }
            }
            _ => {}
        }
    }
    if !seen_metadata {
        return Err(not_a_recording("no `sinew` metadata record".to_owned()));
    }
    Ok(recording)
}

/// The largest record or decompressed chunk read, bytes. The writer's chunks are about a megabyte; a corrupt
/// length or size field must give an error, not an allocation of exabytes (which aborts the process).
const RECORD_LENGTH_LIMIT: usize = 256 << 20;

/// Every record of an MCAP file in order, chunks unpacked, with the end magic optional (a truncated file reads
/// up to the cut) and every length bounded by [`RECORD_LENGTH_LIMIT`].
struct Records<'a> {
    buf: &'a [u8],
    total: usize,
    reader: mcap::sans_io::LinearReader,
}

impl<'a> Records<'a> {
    /// Bytes of the file consumed so far (the reader reads a record or a chunk at a time, so an error lies
    /// within the last one read).
    fn offset(&self) -> usize {
        self.total - self.buf.len()
    }

    fn new(buf: &'a [u8]) -> Self {
        Self {
            buf,
            total: buf.len(),
            reader: mcap::sans_io::LinearReader::new_with_options(
                mcap::sans_io::LinearReaderOptions::default()
                    .with_skip_end_magic(true)
                    // A chunk whose bytes were changed is damage as a whole, before any of its records is
                    // used: a change inside a message no channel decodes would otherwise pass unseen.
                    .with_prevalidate_chunk_crcs(true)
                    .with_record_length_limit(RECORD_LENGTH_LIMIT),
            ),
        }
    }
}

impl Iterator for Records<'_> {
    type Item = mcap::McapResult<mcap::records::Record<'static>>;

    fn next(&mut self) -> Option<Self::Item> {
        while let Some(event) = self.reader.next_event() {
            match event {
                Ok(mcap::sans_io::LinearReadEvent::ReadRequest(need)) => {
                    let len = need.min(self.buf.len());
                    self.reader.insert(len).copy_from_slice(&self.buf[..len]);
                    self.reader.notify_read(len);
                    self.buf = &self.buf[len..];
                }
                Ok(mcap::sans_io::LinearReadEvent::Record { data, opcode }) => {
                    return Some(mcap::parse_record(opcode, data).map(|r| r.into_owned()));
                }
                Err(e) => return Some(Err(e)),
            }
        }
        None
    }
}

fn damage_at(recording: &Recording, offset: usize, what: &str) -> String {
    match recording.ticks.last() {
        Some(last) => format!(
            "{what} (near byte {offset}); read {} ticks, the last complete one tick {}",
            recording.ticks.len(),
            last.tick
        ),
        None => format!("{what} (near byte {offset}); no tick could be read"),
    }
}

fn check_versions(path: &Path, metadata: &BTreeMap<String, String>) -> Result<(), ReadError> {
    let format = metadata.get("format_version").cloned().unwrap_or_default();
    if format != FORMAT_VERSION.to_string() {
        return Err(ReadError::Version {
            path: path.to_owned(),
            what: "recording format",
            found: format,
            expected: FORMAT_VERSION.to_string(),
        });
    }
    let protocol = metadata
        .get("protocol_version")
        .cloned()
        .unwrap_or_default();
    if protocol != sinew_protocol::PROTOCOL_VERSION.to_string() {
        return Err(ReadError::Version {
            path: path.to_owned(),
            what: "protocol version",
            found: protocol,
            expected: sinew_protocol::PROTOCOL_VERSION.to_string(),
        });
    }
    Ok(())
}

impl Recording {
    /// Write the world's files into `dir` (which must exist) and load the world from there.
    pub fn load_world(&self, dir: &Path) -> Result<World, ReadError> {
        let world_error = |source: WorldError| ReadError::World {
            path: self.path.clone(),
            source: Box::new(source),
        };
        let io_error = |file: &Path, e: std::io::Error| ReadError::Read {
            path: file.to_owned(),
            message: format!("writing the recorded world out: {e}"),
        };
        for (name, data) in &self.files {
            if !is_plain_relative(Path::new(name)) {
                return Err(ReadError::NotARecording {
                    path: self.path.clone(),
                    message: format!("it names a world file `{name}` outside its folder"),
                });
            }
            let file = dir.join(name);
            if let Some(parent) = file.parent() {
                std::fs::create_dir_all(parent).map_err(|e| io_error(parent, e))?;
            }
            std::fs::write(&file, data).map_err(|e| io_error(&file, e))?;
        }
        let world_file = dir.join(&self.files[0].0);
        load_world(&world_file).map_err(world_error)
    }
}
