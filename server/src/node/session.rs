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
    if options.config_file.is_none() {
        // The lease this server announces: how long a router or peer keeps its session (and its presence
        // token) after hearing nothing from it. A killed server's QUIC (UDP) links end without a word, so
        // with zenoh's 10 s default a router kept the dead server's token that long and a new server for
        // the scene refused to start beside it.
        config
            .insert_json5(
                "transport/link/tx/lease",
                &SERVER_LINK_LEASE.as_millis().to_string(),
            )
            .map_err(|e| format!("zenoh config `transport/link/tx/lease`: {e}"))?;
    }
    zenoh::open(config).wait()
}

/// The link lease a server announces (`sinew_protocol::network::LINK_LEASE_MS`, the devices' and the lab
/// router's too): its sessions end this long after it dies silently (a kill on a QUIC link). Its stats, deltas
/// and forces keep its links alive.
pub const SERVER_LINK_LEASE: std::time::Duration =
    std::time::Duration::from_millis(sinew_protocol::network::LINK_LEASE_MS);

/// How long a starting server waits for a live server of its scene to leave before refusing: a server that
/// just died silently is still present until its lease ends.
pub const DEPARTURE_WAIT: std::time::Duration =
    std::time::Duration::from_millis(SERVER_LINK_LEASE.as_millis() as u64 + 1500);

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
