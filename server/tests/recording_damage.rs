//! A damaged recording is read up to the damage or refused, never a panic or an abort, wherever the damage
//! lies: a short two-device session on the pad is recorded (the real recorder thread and MCAP writer), then
//! 64 bytes are scrambled at each of 120 places in turn. What reads must replay exactly as far as it goes
//! (checked at every fourth place: a replay is as slow as the session).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup should panic loudly

mod common;

use sinew_server::recording::{FinalState, Recorder, TickRecord, read_recording, replay};
use sinew_server::world::load_world;

#[test]
fn scrambled_bytes_anywhere_give_an_error_or_an_exact_prefix_never_a_crash() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../worlds/pad.toml");
    let world = load_world(&path).unwrap();
    let file = std::env::temp_dir().join(format!("sinew-damage-{}.mcap", std::process::id()));
    let (recorder, mut tap) = Recorder::start(&file, &world).unwrap();
    let mut tick = common::server_tick(&world);
    let mut out = [None; 2];
    let ticks = 400u64;
    for k in 0..ticks {
        let depth = (k as f32 / 300.0).min(1.0) * 5.0;
        let pose = |x: f32| common::pose_at(k + 1, [x, 0.0, 4.0 - depth]);
        let inputs = [pose(0.0), pose(2.0)];
        tick.step(&inputs, &[None, None], &mut out);
        tap.offer(&TickRecord::new(k, &inputs, &[None, None], &out));
        // Let the writer keep up (the queue holds 256 ticks).
        if k % 100 == 99 {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    }
    tap.finish(FinalState {
        ticks,
        positions_mm: vec![
            tick.positions_mm(0)
                .unwrap()
                .iter()
                .map(|p| [p.x, p.y, p.z])
                .collect(),
        ],
    });
    let summary = recorder.join();
    assert_eq!((summary.ticks, summary.dropped), (ticks, 0), "{summary:?}");
    let bytes = std::fs::read(&file).unwrap();
    let _ = std::fs::remove_file(&file);
    let clean =
        std::env::temp_dir().join(format!("sinew-damage-{}-clean.mcap", std::process::id()));
    std::fs::write(&clean, &bytes).unwrap();
    let whole = read_recording(&clean).unwrap();
    let _ = std::fs::remove_file(&clean);
    let dir = std::env::temp_dir().join(format!("sinew-damage-{}-world", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let world = whole.load_world(&dir).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(replay(&whole, &world).unwrap().exact());

    let damaged =
        std::env::temp_dir().join(format!("sinew-damage-{}-bad.mcap", std::process::id()));

    // The first chunk claims 4 EB of content: an error, not an allocation that aborts the process. Records are
    // an opcode, a u64 length and the body; the file starts with an 8-byte magic.
    let mut chunk = 8;
    while bytes[chunk] != 0x06 {
        let len = u64::from_le_bytes(bytes[chunk + 1..chunk + 9].try_into().unwrap()) as usize;
        chunk += 9 + len;
    }
    let mut huge = bytes.clone();
    huge[chunk + 25..chunk + 33].copy_from_slice(&(1u64 << 62).to_le_bytes());
    std::fs::write(&damaged, &huge).unwrap();
    match read_recording(&damaged) {
        Ok(r) => assert!(r.damage.is_some() || r.ticks.is_empty(), "{:?}", r.damage),
        Err(e) => println!("a 4 EB chunk: {e}"),
    }

    let (mut refused, mut salvaged, mut intact) = (0, 0, 0);
    for i in 0..120usize {
        let at = i * (bytes.len() - 64) / 120;
        let mut copy = bytes.clone();
        for (j, b) in copy[at..at + 64].iter_mut().enumerate() {
            *b ^= 0xa5 ^ (j as u8);
        }
        std::fs::write(&damaged, &copy).unwrap();
        match read_recording(&damaged) {
            Err(e) => {
                assert!(e.to_string().contains("sinew-damage"), "{e}");
                refused += 1;
            }
            Ok(r) => {
                if let Some(damage) = &r.damage {
                    assert!(damage.contains("byte"), "{damage}");
                    salvaged += 1;
                } else {
                    intact += 1;
                }
                if i % 4 != 0 {
                    continue;
                }
                // Whatever was read replays exactly (a scrambled tick that still decodes is a different
                // input, so only the ticks before the damage are held to it).
                let same = r
                    .ticks
                    .iter()
                    .zip(&whole.ticks)
                    .take_while(|(a, b)| a == b)
                    .count();
                let good = r.ticks[..same].to_vec();
                let prefix = sinew_server::recording::Recording {
                    ticks: good,
                    final_state: None,
                    ..r.clone()
                };
                let outcome = replay(&prefix, &world).unwrap();
                assert_eq!(
                    outcome.force_mismatches, 0,
                    "damage at byte {at}: {outcome:?}"
                );
            }
        }
    }
    let _ = std::fs::remove_file(&damaged);
    println!(
        "{} bytes, 120 places: refused {refused}, read up to the damage {salvaged}, read whole {intact}",
        bytes.len()
    );
    assert!(salvaged > 0, "no damage was detected in a chunk");
}
