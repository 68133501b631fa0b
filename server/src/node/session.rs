//! Opening the zenoh session from [`NetworkOptions`].

use sinew_protocol::network::NetworkOptions;
use zenoh::Wait;

/// Open a zenoh session: the config file first (if any), then the options' entries on top.
pub fn open_session(options: &NetworkOptions) -> zenoh::Result<zenoh::Session> {
    let mut config = match &options.config_file {
        Some(path) => zenoh::Config::from_file(path)?,
        None => zenoh::Config::default(),
    };
    for (key, value) in options.config_entries() {
        config
            .insert_json5(key, &value)
            .map_err(|e| format!("zenoh config `{key}` = {value}: {e}"))?;
    }
    zenoh::open(config).wait()
}
