//! The zenoh endpoint options every role shares, as plain data.
//!
//! The embedded default is zenoh peer mode on loopback with multicast scouting off: the server listens on
//! [`DEFAULT_ENDPOINT`], the other roles connect to it. Each role turns these options into zenoh config
//! entries with [`NetworkOptions::config_entries`] (JSON5 key/value pairs for `Config::insert_json5`), so
//! this crate needs no zenoh dependency.

/// Where the server listens and the others connect by default.
pub const DEFAULT_ENDPOINT: &str = "tcp/127.0.0.1:7447";

/// Endpoints and an optional zenoh config file.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct NetworkOptions {
    /// zenoh config file (JSON5) loaded first; the entries below override it.
    pub config_file: Option<std::path::PathBuf>,
    /// Endpoints to listen on, e.g. `tcp/127.0.0.1:7447`.
    pub listen: Vec<String>,
    /// Endpoints to connect to.
    pub connect: Vec<String>,
    /// zenoh mode: `peer` (default) or `client` (through a zenohd router).
    pub mode: Option<String>,
}

impl NetworkOptions {
    /// The server's default: listen on [`DEFAULT_ENDPOINT`].
    pub fn server_default() -> Self {
        Self {
            listen: vec![DEFAULT_ENDPOINT.to_owned()],
            ..Self::default()
        }
    }

    /// A client role's default: connect to [`DEFAULT_ENDPOINT`].
    pub fn client_default() -> Self {
        Self {
            connect: vec![DEFAULT_ENDPOINT.to_owned()],
            ..Self::default()
        }
    }

    /// JSON5 `(key, value)` entries to insert into a zenoh config: mode, endpoints, scouting off. Listening
    /// endpoints default to none (not zenoh's `tcp/[::]:0` on every interface). When a config file is given,
    /// only the explicitly set options override it.
    pub fn config_entries(&self) -> Vec<(&'static str, String)> {
        let list = |items: &[String]| {
            let quoted: Vec<String> = items.iter().map(|e| format!("{e:?}")).collect();
            format!("[{}]", quoted.join(","))
        };
        let mut entries = Vec::new();
        let defaults = self.config_file.is_none();
        if let Some(mode) = &self.mode {
            entries.push(("mode", format!("{mode:?}")));
        } else if defaults {
            entries.push(("mode", "\"peer\"".to_owned()));
        }
        if !self.listen.is_empty() || defaults {
            entries.push(("listen/endpoints", list(&self.listen)));
        }
        if !self.connect.is_empty() || defaults {
            entries.push(("connect/endpoints", list(&self.connect)));
        }
        if defaults {
            entries.push(("scouting/multicast/enabled", "false".to_owned()));
            // A device's transport may hold a TCP and a UDP link to the server: reliable messages take TCP,
            // poses and forces (best effort) take UDP, so a lost packet never holds later forces back.
            entries.push(("transport/unicast/max_links", "2".to_owned()));
        }
        entries
    }
}
