//! Turns the shared [`NetworkOptions`] into a zenoh [`zenoh::Config`].
//!
//! Owns: the one place the viewer builds a zenoh config (file first, then the option entries on top).
//! Must not: open a session or pick endpoints of its own; defaults live in `sinew_protocol::network`.

use sinew_protocol::network::NetworkOptions;

use crate::error::ViewerError;

/// A zenoh config from `network`: its config file (if any), overridden by its entries.
pub fn zenoh_config(network: &NetworkOptions) -> Result<zenoh::Config, ViewerError> {
    network
        .check()
        .map_err(|e| ViewerError::zenoh("checking the network options", e))?;
    let mut config = match &network.config_file {
        Some(path) => zenoh::Config::from_file(path).map_err(|e| {
            ViewerError::zenoh(format!("loading config file {}", path.display()), e)
        })?,
        None => zenoh::Config::default(),
    };
    for (key, value) in network.config_entries() {
        config
            .insert_json5(key, &value)
            .map_err(|e| ViewerError::zenoh(format!("setting `{key}` to {value}"), e))?;
    }
    if network.config_file.is_none() {
        // zenoh's open waits (500 ms) for the declarations of every peer it connects to, and warns `Scouting
        // delay elapsed before start conditions are met` when they come later: on a loaded 2-core runner a
        // server busy starting its scene answered later than that (CI, 2026-11-29). The viewer does not need
        // the wait: its first snapshot query, if no queryable is known yet, fails quietly and is retried at
        // once when the server's presence arrives (`client.rs`), and deltas are subscribed before it.
        config
            .insert_json5(RETURN_WITHOUT_DECLARATIONS.0, RETURN_WITHOUT_DECLARATIONS.1)
            .map_err(|e| {
                ViewerError::zenoh(format!("setting `{}`", RETURN_WITHOUT_DECLARATIONS.0), e)
            })?;
    }
    Ok(config)
}

/// The session's open returns without waiting for the connected peers' declarations.
const RETURN_WITHOUT_DECLARATIONS: (&str, &str) =
    ("open/return_conditions/connect_scouted", "false");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_client_options_make_a_config() {
        assert!(zenoh_config(&NetworkOptions::client_default()).is_ok());
    }

    #[test]
    fn the_viewer_does_not_wait_for_the_servers_declarations_to_open() {
        let config = zenoh_config(&NetworkOptions::client_default()).unwrap();
        assert_eq!(
            config.get_json(RETURN_WITHOUT_DECLARATIONS.0).unwrap(),
            RETURN_WITHOUT_DECLARATIONS.1
        );
    }

    #[test]
    fn a_client_of_a_router_makes_a_config_that_keeps_trying_it() {
        let options = NetworkOptions {
            connect: vec!["tcp/10.0.0.1:7447".to_owned()],
            mode: Some("client".to_owned()),
            ..NetworkOptions::default()
        };
        let config = zenoh_config(&options).unwrap();
        assert_eq!(config.get_json("connect/timeout_ms").unwrap(), "10000");
    }

    #[test]
    fn bad_endpoint_is_a_clear_error() {
        let options = NetworkOptions {
            connect: vec!["nonsense".to_owned()],
            ..NetworkOptions::default()
        };
        let err = zenoh_config(&options).unwrap_err().to_string();
        assert!(err.contains("connect/endpoints"), "{err}");
    }

    #[test]
    fn missing_config_file_names_the_file() {
        let options = NetworkOptions {
            config_file: Some("/nonexistent/sinew-zenoh.json5".into()),
            ..NetworkOptions::default()
        };
        let err = zenoh_config(&options).unwrap_err().to_string();
        assert!(err.contains("/nonexistent/sinew-zenoh.json5"), "{err}");
    }
}
