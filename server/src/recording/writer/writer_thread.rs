//! The writer thread: every item from the queue written to the file, each tick's exact record with its
//! JSON views and events, each wire message on its key's channel, and the final state.
//!
//! Owns: [`write_loop`], which runs until the handle ends it, returns the tick boxes to the tap and stops
//! writing, once, at the first write error. Must not: block the sim thread (it only ever reads the
//! queue) or stop the session.

use super::*;
use crate::recording::WIRE_ENCODING;
use crate::recording::queue::WireItem;
use crate::recording::tick_record::TickMessage;

pub(super) fn write_loop<W: std::io::Write + std::io::Seek>(
    mut out: mcap::Writer<W>,
    mut channels: Channels,
    items: Receiver<Item>,
    give_back: Option<SyncSender<Box<TickRecord>>>,
    tick_ns: u64,
    mut summary: RecordSummary,
    shared: &WriterShared<'_>,
) -> RecordSummary {
    let WriterShared {
        dropped,
        failed,
        wire_in_flight,
    } = *shared;
    let mut sequence = 0u32;
    let mut bytes = Vec::with_capacity(4096);
    let fail = |summary: &mut RecordSummary, what: String| {
        if summary.error.is_none() {
            tracing::error!(
                file = %summary.path.display(),
                "recording stopped: {what}; the session goes on unrecorded"
            );
            summary.error = Some(what);
            failed.store(true, Ordering::Relaxed);
        }
    };
    for item in items {
        match item {
            Item::Tick(record) => {
                if summary.error.is_none() {
                    let time_ns = record.tick.saturating_mul(tick_ns);
                    let message = TickMessage::from(record.as_ref());
                    let result = write_tick(
                        &mut out,
                        &channels,
                        &message,
                        time_ns,
                        &mut sequence,
                        &mut bytes,
                    )
                    .and_then(|()| {
                        write_events(&mut out, &channels, &record, time_ns, &mut sequence)
                    });
                    match result {
                        Ok(()) => summary.ticks += 1,
                        Err(e) => fail(&mut summary, e),
                    }
                }
                if let Some(give_back) = &give_back {
                    let _ = give_back.try_send(record);
                }
            }
            Item::Wire(item) => {
                wire_in_flight.fetch_sub(1, Ordering::AcqRel);
                if summary.error.is_none() {
                    match write_wire(&mut out, &mut channels, &item, &mut sequence) {
                        Ok(()) => summary.wire_items += 1,
                        Err(e) => fail(&mut summary, e),
                    }
                }
            }
            Item::End => break,
            Item::Final(state) => {
                if summary.error.is_none() {
                    let time_ns = state.ticks.saturating_mul(tick_ns);
                    let result = postcard::to_allocvec(&state)
                        .map_err(|e| e.to_string())
                        .and_then(|data| {
                            write_message(
                                &mut out,
                                channels.final_state,
                                &mut sequence,
                                time_ns,
                                &data,
                            )
                        });
                    match result {
                        Ok(()) => summary.final_state = true,
                        Err(e) => fail(&mut summary, e),
                    }
                }
            }
        }
    }
    if summary.error.is_none()
        && let Err(e) = out.finish()
    {
        fail(&mut summary, describe(&e));
    }
    summary.dropped = dropped.load(Ordering::Relaxed);
    summary
}

fn write_tick<W: std::io::Write + std::io::Seek>(
    out: &mut mcap::Writer<W>,
    channels: &Channels,
    message: &TickMessage,
    time_ns: u64,
    sequence: &mut u32,
    bytes: &mut Vec<u8>,
) -> Result<(), String> {
    bytes.clear();
    let data = postcard::to_extend(message, std::mem::take(bytes)).map_err(|e| e.to_string())?;
    write_message(out, channels.ticks, sequence, time_ns, &data)?;
    *bytes = data;
    for (device, &(pose_channel, force_channel)) in message.devices.iter().zip(&channels.devices) {
        if let Some(pose) = &device.pose {
            let json = crate::recording::json_view::pose_json(pose, device.age_s, device.usable)?;
            write_message(out, pose_channel, sequence, time_ns, json.as_bytes())?;
        }
        if let Some(force) = &device.force {
            let json = crate::recording::json_view::force_json(force)?;
            write_message(out, force_channel, sequence, time_ns, json.as_bytes())?;
        }
    }
    Ok(())
}

fn write_wire<W: std::io::Write + std::io::Seek>(
    out: &mut mcap::Writer<W>,
    channels: &mut Channels,
    item: &WireItem,
    sequence: &mut u32,
) -> Result<(), String> {
    match item {
        WireItem::Sample {
            key,
            log_time_ns,
            payload,
        } => {
            let channel = match channels.wire.get(key) {
                Some(&id) => id,
                None => {
                    let mut metadata = BTreeMap::new();
                    metadata.insert(
                        "format".to_owned(),
                        "sinew wire envelope: u16 LE protocol version, u8 message kind, u64 LE sender, \
                         postcard body"
                            .to_owned(),
                    );
                    let id = out
                        .add_channel(0, key, WIRE_ENCODING, &metadata)
                        .map_err(|e| describe(&e))?;
                    channels.wire.insert(key.clone(), id);
                    id
                }
            };
            write_message(out, channel, sequence, *log_time_ns, payload)?;
            // JSON views of the low-rate messages an instructor reads in Foxglove.
            let view = if key.ends_with("/tools") {
                sinew_protocol::decode::<sinew_protocol::ToolStates>(payload)
                    .ok()
                    .map(|m| (channels.tools_json, serde_json::to_vec(&m)))
            } else if key.ends_with("/stats") {
                sinew_protocol::decode::<sinew_protocol::ServerStats>(payload)
                    .ok()
                    .map(|m| (channels.stats_json, serde_json::to_vec(&m)))
            } else {
                None
            };
            if let Some((channel, json)) = view {
                let json = json.map_err(|e| e.to_string())?;
                write_message(out, channel, sequence, *log_time_ns, &json)?;
            }
            Ok(())
        }
        WireItem::Presence {
            key,
            joined,
            log_time_ns,
        } => {
            let json = crate::recording::json_view::presence_json(key, *joined)?;
            write_message(
                out,
                channels.presence_json,
                sequence,
                *log_time_ns,
                json.as_bytes(),
            )
        }
    }
}

fn write_events<W: std::io::Write + std::io::Seek>(
    out: &mut mcap::Writer<W>,
    channels: &Channels,
    record: &TickRecord,
    time_ns: u64,
    sequence: &mut u32,
) -> Result<(), String> {
    for event in record.events() {
        let device = channels
            .device_ids
            .get(usize::from(event.tool))
            .map_or("", String::as_str);
        let json = crate::recording::json_view::event_json(event, device)?;
        write_message(out, channels.events, sequence, time_ns, json.as_bytes())?;
    }
    Ok(())
}

fn write_message<W: std::io::Write + std::io::Seek>(
    out: &mut mcap::Writer<W>,
    channel_id: u16,
    sequence: &mut u32,
    time_ns: u64,
    data: &[u8],
) -> Result<(), String> {
    *sequence = sequence.wrapping_add(1);
    out.write_to_known_channel(
        &mcap::records::MessageHeader {
            channel_id,
            sequence: *sequence,
            log_time: time_ns,
            publish_time: time_ns,
        },
        data,
    )
    .map_err(|e| describe(&e))
}
