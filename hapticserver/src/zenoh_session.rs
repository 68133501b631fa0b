//! Opening a zenoh session from the shared [`NetworkOptions`].
//!
//! Owns: the translation of [`NetworkOptions`] (config file, endpoints, mode, scouting off) into a
//! `zenoh::Config` and the session open. Must not: declare anything on the session (that is
//! [`crate::haptic_server`]).

use sinew_protocol::network::NetworkOptions;
use zenoh::Wait;

use crate::error::HapticError;

/// Build the zenoh config for `network`: its config file first (if any), then its entries on top.
pub fn zenoh_config(network: &NetworkOptions) -> Result<zenoh::Config, HapticError> {
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
    Ok(config)
}

/// Open a session for `network`.
pub fn open_session(network: &NetworkOptions) -> Result<zenoh::Session, HapticError> {
    let config = zenoh_config(network)?;
    zenoh::open(config)
        .wait()
        .map_err(HapticError::zenoh("opening the session"))
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
        assert!(zenoh_config(&NetworkOptions::device_default()).is_ok());
    }
}
