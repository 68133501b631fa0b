//! Opening a zenoh session from the shared [`NetworkOptions`].
//!
//! Owns: the translation of [`NetworkOptions`] (config file, endpoints, mode, scouting off) into a
//! `zenoh::Config`, the session open, and the wait for the multilink transport's UDP link. Must not: declare
//! anything on the session (that is [`crate::haptic_server`]).

use std::time::{Duration, Instant};

use sinew_protocol::network::NetworkOptions;
use zenoh::Wait;

use crate::error::HapticError;

/// Build the zenoh config for `network`: its config file first (if any), then its entries on top.
pub fn zenoh_config(network: &NetworkOptions) -> Result<zenoh::Config, HapticError> {
    network.check().map_err(|detail| HapticError::Zenoh {
        what: "checking the network options".to_owned(),
        detail,
    })?;
    let mut config = match &network.config_file {
        Some(path) => zenoh::Config::from_file(path).map_err(HapticError::zenoh(format!(
            "loading config file {}",
            path.display()
        )))?,
        None => zenoh::Config::default(),
    };
    for (key, value) in network.config_entries() {
        config
            .insert_json5(key, &value)
            .map_err(HapticError::zenoh(format!("setting {key} = {value}")))?;
    }
    if network.config_file.is_none() {
        // zenoh's open waits (500 ms) until every connector has the peer's declarations; the UDP twin of a
        // TCP endpoint joins a transport that already has them and never reports in, so every start waited
        // the whole delay and warned `Scouting delay elapsed before start conditions are met`. The device
        // does not need that wait: it waits for its UDP link itself (`wait_for_udp_link`), and a first pose
        // sent before the server's subscriber is known is only one of a 1 kHz stream.
        config
            .insert_json5("open/return_conditions/connect_scouted", "false")
            .map_err(HapticError::zenoh(
                "setting open/return_conditions/connect_scouted",
            ))?;
        // The lease this device announces is how long the server keeps a link it hears nothing on. A UDP link
        // can be left half open: the server adds it to the transport and then its last handshake reply is
        // lost, so the device never has it while the server sends every best-effort force down it. zenoh's
        // default lease (10 s) left the device deaf that long (and refused its next UDP link, the transport
        // being at `max_links`); with this one the server lets the dead link go within DEVICE_LINK_LEASE and
        // the device's next try (every 250 ms at most) opens a UDP link that works.
        config
            .insert_json5(
                "transport/link/tx/lease",
                &DEVICE_LINK_LEASE.as_millis().to_string(),
            )
            .map_err(HapticError::zenoh("setting transport/link/tx/lease"))?;
    }
    Ok(config)
}

/// The link lease a device announces (`sinew_protocol::network::LINK_LEASE_MS`, the server's and the lab
/// router's too): the server drops a link of this device's that has carried nothing for this long. Poses
/// (1 kHz) keep their link alive.
pub const DEVICE_LINK_LEASE: Duration =
    Duration::from_millis(sinew_protocol::network::LINK_LEASE_MS);

/// Open a session for `network`.
pub fn open_session(network: &NetworkOptions) -> Result<zenoh::Session, HapticError> {
    let config = zenoh_config(network)?;
    zenoh::open(config)
        .wait()
        .map_err(HapticError::zenoh("opening the session"))
}

/// How long a starting device waits for the UDP link of its multilink transport before it runs on TCP alone.
/// zenoh opens the TCP link first and the UDP one a few round trips later (or, when a handshake packet is lost,
/// after the 1 s link timeout); until then poses and forces ride TCP, where one lost segment holds later forces
/// past the 50 ms silence rule (seen as silences at contact onset through a lossy 100 ms path).
/// Longer than [`DEVICE_LINK_LEASE`], so a device whose first UDP link was left half open starts on the
/// UDP link that replaces it.
pub const UDP_LINK_WAIT: Duration = Duration::from_secs(4);

/// Whether `network` asks for a UDP link (a `udp/...` connect endpoint).
pub fn wants_udp_link(network: &NetworkOptions) -> bool {
    network.connect.iter().any(|e| e.starts_with("udp/"))
}

/// Wait until `session` holds a UDP link, polling every 5 ms, for at most `timeout`: how long it took, or
/// `None` if none came.
pub fn wait_for_udp_link(session: &zenoh::Session, timeout: Duration) -> Option<Duration> {
    let start = Instant::now();
    loop {
        let has_udp = session
            .info()
            .links()
            .wait()
            .any(|link| link.dst().protocol().as_str() == "udp");
        if has_udp {
            return Some(start.elapsed());
        }
        if start.elapsed() >= timeout {
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_endpoints_and_missing_files_are_named() {
        let network = NetworkOptions {
            connect: vec!["not an endpoint".to_owned()],
            ..NetworkOptions::default()
        };
        let err = zenoh_config(&network).unwrap_err().to_string();
        assert!(err.contains("connect/endpoints"), "{err}");
        let network = NetworkOptions {
            config_file: Some("/nonexistent/zenoh.json5".into()),
            ..NetworkOptions::default()
        };
        let err = zenoh_config(&network).unwrap_err().to_string();
        assert!(err.contains("/nonexistent/zenoh.json5"), "{err}");
        let config = zenoh_config(&NetworkOptions::device_default()).unwrap();
        assert_eq!(
            config.get_json("transport/link/tx/lease").unwrap(),
            DEVICE_LINK_LEASE.as_millis().to_string()
        );
        assert!(UDP_LINK_WAIT > DEVICE_LINK_LEASE);
    }
}
