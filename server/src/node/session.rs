//! Opening the zenoh session from [`NetworkOptions`].

use sinew_protocol::network::NetworkOptions;
use zenoh::Wait;

/// Open a zenoh session: the config file first (if any), then the options' entries on top.
pub fn open_session(options: &NetworkOptions) -> zenoh::Result<zenoh::Session> {
    options.check()?;
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

/// How long a server waits for answers when it asks who else is live for its scene, ms.
pub const LIVE_SERVER_QUERY_MS: u64 = 500;

/// The presence keys of servers already live for `keys`' scene and reachable from `session`.
pub fn live_servers(
    session: &zenoh::Session,
    keys: &sinew_protocol::keys::SceneKeys,
) -> zenoh::Result<Vec<String>> {
    let replies = session
        .liveliness()
        .get(keys.all_presence(sinew_protocol::Role::Server))
        .timeout(std::time::Duration::from_millis(LIVE_SERVER_QUERY_MS))
        .wait()?;
    let mut found = Vec::new();
    while let Ok(reply) = replies.recv() {
        if let Ok(sample) = reply.result() {
            found.push(sample.key_expr().to_string());
        }
    }
    Ok(found)
}
