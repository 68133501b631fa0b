//! The zenoh endpoint options every role shares, as plain data.
//!
//! The embedded default is zenoh peer mode on loopback with multicast scouting off: the server listens on
//! [`DEFAULT_ENDPOINT`], the other roles connect to it. Each role turns these options into zenoh config
//! entries with [`NetworkOptions::config_entries`] (JSON5 key/value pairs for `Config::insert_json5`), so
//! this crate needs no zenoh dependency.

/// The server's TCP endpoint by default (viewers connect to it alone).
pub const DEFAULT_ENDPOINT: &str = "tcp/127.0.0.1:7447";

/// Where the server listens and devices connect by default: the same port over TCP and UDP. A device holds one
/// zenoh transport with two links: reliable messages (declarations, hellos, deltas) take TCP, best-effort poses
/// and forces take UDP, where a lost packet never holds later ones back (BENCHMARKS.md, "Transport for poses
/// and forces under loss": TCP alone left 400+ force gaps > 50 ms a minute at 1% loss, multilink none).
pub const DEFAULT_DEVICE_ENDPOINTS: [&str; 2] = ["tcp/127.0.0.1:7447", "udp/127.0.0.1:7447"];

/// zenoh's link open and accept timeout, ms. zenoh's 10 s default made a device whose UDP handshake packet was
/// lost wait 10 s for its UDP link (forces on TCP meanwhile); at 1 s every trial of the lossy bench joined
/// within 2.2 s. A handshake is a few round trips, so 1 s still leaves room for a 200 ms path.
pub const LINK_TIMEOUT_MS: u64 = 1000;

/// How long a client of a router keeps trying to reach it when its session opens, ms (zenoh's default for a
/// client: one try). A QUIC handshake whose first flight is lost waits out its probe timeout (about a second)
/// and then the link's open timeout ends it: through a lab path with 50 ms round trips and 2% loss a viewer
/// failed to start that way (`Unable to connect to any of [quic/...]`); retried, it joins.
pub const CLIENT_CONNECT_TIMEOUT_MS: u64 = 10_000;

/// The link lease a device, a server and a lab's router announce, ms (zenoh's default: 10 s): whoever is at
/// the other end of a link drops it (and a session that has no link left, with its presence tokens) once it has
/// carried nothing this long. Each role inserts it for its own reason (a device's half-open UDP link, a server
/// or a router killed silently on QUIC: see `hapticserver::process::zenoh_session`, the server's `node::session`
/// and [`crate::zenoh_config_file::lab_router_config`]); one value, so the three stay equal. A link with
/// nothing to send carries a keep-alive every quarter lease; over a 100 ms path with 5% loss a TCP link stalls
/// this long only if one segment is lost four times running (retransmits after about 0.3, 0.6, 1.2 s).
pub const LINK_LEASE_MS: u64 = 3000;

/// First retry period of a lost connect endpoint, ms (doubling up to [`RETRY_MAX_MS`]).
pub const RETRY_INIT_MS: u64 = 50;

/// Longest retry period of a lost connect endpoint, ms: the worst-case wait between a server's return and
/// the next attempt to reach it.
pub const RETRY_MAX_MS: u64 = 250;

/// The UDP endpoint on the same address and port as a TCP one (`tcp/h:p` -> `udp/h:p`); `None` for any other
/// protocol.
pub fn udp_twin(endpoint: &str) -> Option<String> {
    endpoint
        .strip_prefix("tcp/")
        .map(|rest| format!("udp/{rest}"))
}

/// `endpoint` followed by its UDP twin when it is a TCP endpoint: what a device connects to (or a server
/// listens on) for multilink.
pub fn with_udp_twin(endpoint: &str) -> Vec<String> {
    std::iter::once(endpoint.to_owned())
        .chain(udp_twin(endpoint))
        .collect()
}

/// The one link protocol of a secured session: QUIC, whose TLS 1.3 handshake does the mutual authentication
/// with the `transport/link/tls/*` files. Each connection runs zenoh's mixed reliability (endpoint metadata
/// `mixed_rel`): reliable messages on a stream, best-effort poses and forces as QUIC datagrams, so a lost
/// packet never holds later forces back, as the plain TCP + UDP multilink does. zenoh's `tls/` (TLS over TCP)
/// is not used: zenoh 1.10's TLS link reads and writes one rustls stream from two tasks at once, which is
/// unsound (eclipse-zenoh/zenoh#2557) and aborted our security test with a corrupted heap.
pub const SECURE_PROTOCOL: &str = "quic";

/// `endpoint` as a secured session uses it: a `quic/` endpoint that names no `mixed_rel` gets `mixed_rel=value`
/// in its metadata (`1` to connect, `auto` to listen, so a peer without it still joins on one stream); any other
/// endpoint, or any endpoint of a plain session, is returned as given.
fn secure_endpoint(endpoint: &str, secure: bool, value: &str) -> String {
    if !secure || !endpoint.starts_with("quic/") || endpoint.contains("mixed_rel=") {
        return endpoint.to_owned();
    }
    let (locator, config) = match endpoint.split_once('#') {
        Some((locator, config)) => (locator, Some(config)),
        None => (endpoint, None),
    };
    let separator = if locator.contains('?') { ';' } else { '?' };
    let mut out = format!("{locator}{separator}mixed_rel={value}");
    if let Some(config) = config {
        out.push('#');
        out.push_str(config);
    }
    out
}

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
    /// Mutual TLS with these files: every endpoint is `quic/...` (QUIC's TLS 1.3), only QUIC links are opened
    /// or accepted, and the certificate's common name is this role's identity ([`crate::security`]).
    pub tls: Option<crate::security::TlsFiles>,
    /// zenoh access-control rules (JSON5) this node enforces on what reaches it (a server's:
    /// [`crate::security::access_control_json5`]); needs `tls`, whose certificates name the roles.
    pub access_control: Option<String>,
}

impl NetworkOptions {
    /// The server's default: listen on [`DEFAULT_DEVICE_ENDPOINTS`] (TCP and UDP).
    pub fn server_default() -> Self {
        Self {
            listen: DEFAULT_DEVICE_ENDPOINTS.map(str::to_owned).to_vec(),
            ..Self::default()
        }
    }

    /// A device's default: connect to [`DEFAULT_DEVICE_ENDPOINTS`] (TCP and UDP, one transport with two links).
    pub fn device_default() -> Self {
        Self {
            connect: DEFAULT_DEVICE_ENDPOINTS.map(str::to_owned).to_vec(),
            ..Self::default()
        }
    }

    /// A viewer's default: connect to [`DEFAULT_ENDPOINT`] (TCP: a viewer takes only reliable deltas).
    pub fn client_default() -> Self {
        Self {
            connect: vec![DEFAULT_ENDPOINT.to_owned()],
            ..Self::default()
        }
    }

    /// These options with mutual TLS: the role's default TCP endpoints become QUIC ones on the same address and
    /// port, and UDP endpoints are dropped (one QUIC connection carries both: reliable messages on a stream,
    /// best-effort poses and forces as datagrams, see [`SECURE_PROTOCOL`]).
    pub fn secured(mut self, tls: crate::security::TlsFiles) -> Self {
        let to_quic = |list: Vec<String>| -> Vec<String> {
            list.into_iter()
                .filter(|e| !e.starts_with("udp/"))
                .map(|e| match e.strip_prefix("tcp/") {
                    Some(rest) => format!("quic/{rest}"),
                    None => e,
                })
                .collect()
        };
        self.listen = to_quic(self.listen);
        self.connect = to_quic(self.connect);
        self.tls = Some(tls);
        self
    }

    /// The security options agree with the endpoints: with TLS every endpoint is `quic/...` and the files are
    /// readable; without it no endpoint is; access control needs TLS. The error says which flag or endpoint.
    pub fn check(&self) -> Result<(), String> {
        let endpoints = self.listen.iter().chain(&self.connect);
        match &self.tls {
            Some(tls) => {
                if let Some(plain) = endpoints.into_iter().find(|e| !e.starts_with("quic/")) {
                    let why = if plain.starts_with("tls/") {
                        "zenoh's tls/ link is not used: it reads and writes one TLS stream from two tasks at \
                         once, which crashed a test (eclipse-zenoh/zenoh#2557)"
                    } else {
                        "a plain link would bypass TLS"
                    };
                    return Err(format!(
                        "endpoint `{plain}`: with --tls-* every endpoint must be quic/HOST:PORT ({why})"
                    ));
                }
                tls.check()?;
            }
            None => {
                if let Some(tls) = endpoints
                    .into_iter()
                    .find(|e| e.starts_with("quic/") || e.starts_with("tls/"))
                {
                    return Err(format!(
                        "endpoint `{tls}` needs --tls-ca, --tls-cert and --tls-key"
                    ));
                }
                if self.access_control.is_some() {
                    return Err(
                        "access control needs TLS: the certificates name the roles".to_owned()
                    );
                }
            }
        }
        Ok(())
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
        let secure = self.tls.is_some();
        let listen: Vec<String> = self
            .listen
            .iter()
            .map(|e| secure_endpoint(e, secure, "auto"))
            .collect();
        let connect: Vec<String> = self
            .connect
            .iter()
            .map(|e| secure_endpoint(e, secure, "1"))
            .collect();
        if !listen.is_empty() || defaults {
            entries.push(("listen/endpoints", list(&listen)));
        }
        if !connect.is_empty() || defaults {
            entries.push(("connect/endpoints", list(&connect)));
        }
        if defaults {
            entries.push(("scouting/multicast/enabled", "false".to_owned()));
            // A device's transport may hold a TCP and a UDP link to the server: reliable messages take TCP,
            // poses and forces (best effort) take UDP, so a lost packet never holds later forces back.
            entries.push(("transport/unicast/max_links", "2".to_owned()));
            entries.push((
                "transport/unicast/open_timeout",
                LINK_TIMEOUT_MS.to_string(),
            ));
            entries.push((
                "transport/unicast/accept_timeout",
                LINK_TIMEOUT_MS.to_string(),
            ));
            // Peers learn of each other by gossip. A client that does not listen cannot be dialled, yet a client
            // that dialled it waited 500 ms for it on every start and warned `Scouting delay elapsed before start
            // conditions are met`. A role that only connects (device, viewer) talks to the server it connects
            // to, so it dials no gossiped peer; a role that listens (a server) still dials the servers it hears
            // of, which is how two live servers for one scene find each other.
            if self.listen.is_empty() {
                entries.push((
                    "scouting/gossip/autoconnect",
                    "{router:[],peer:[\"router\"]}".to_owned(),
                ));
            }
            if self.mode.as_deref() == Some("client") {
                entries.push(("connect/timeout_ms", CLIENT_CONNECT_TIMEOUT_MS.to_string()));
            }
            // A lost server is retried every 50 ms, backing off to every 250 ms (zenoh's default is 1 s
            // doubling to 4 s): a restarted server is rejoined within about a quarter second of its return.
            entries.push((
                "connect/retry",
                format!(
                    "{{period_init_ms:{RETRY_INIT_MS},period_max_ms:{RETRY_MAX_MS},period_increase_factor:2}}"
                ),
            ));
        }
        if let Some(tls) = &self.tls {
            let path = |p: &std::path::Path| format!("{:?}", p.display().to_string());
            entries.push(("transport/link/tls/root_ca_certificate", path(&tls.ca)));
            entries.push(("transport/link/tls/listen_certificate", path(&tls.cert)));
            entries.push(("transport/link/tls/listen_private_key", path(&tls.key)));
            entries.push(("transport/link/tls/connect_certificate", path(&tls.cert)));
            entries.push(("transport/link/tls/connect_private_key", path(&tls.key)));
            entries.push(("transport/link/tls/enable_mtls", "true".to_owned()));
            entries.push((
                "transport/link/tls/verify_name_on_connect",
                "true".to_owned(),
            ));
            // Only QUIC links, opened or accepted: a gossiped plain locator is never dialled.
            entries.push(("transport/link/protocols", format!("[{SECURE_PROTOCOL:?}]")));
        }
        if let Some(acl) = &self.access_control {
            entries.push(("access_control", acl.clone()));
        }
        entries
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tcp_endpoint_gets_its_udp_twin_and_nothing_else_does() {
        assert_eq!(
            with_udp_twin("tcp/10.0.0.1:7447"),
            vec![
                "tcp/10.0.0.1:7447".to_owned(),
                "udp/10.0.0.1:7447".to_owned()
            ]
        );
        assert_eq!(
            with_udp_twin("udp/10.0.0.1:7447"),
            vec!["udp/10.0.0.1:7447".to_owned()]
        );
        assert_eq!(udp_twin("quic/h:1"), None);
    }

    #[test]
    fn the_defaults_are_multilink_with_short_link_timeouts() {
        assert_eq!(
            NetworkOptions::device_default().connect,
            with_udp_twin(DEFAULT_ENDPOINT)
        );
        assert_eq!(
            NetworkOptions::server_default().listen,
            with_udp_twin(DEFAULT_ENDPOINT)
        );
        let entries = NetworkOptions::server_default().config_entries();
        let value = |key: &str| {
            entries
                .iter()
                .find(|(k, _)| *k == key)
                .map(|(_, v)| v.clone())
        };
        assert_eq!(value("transport/unicast/max_links").as_deref(), Some("2"));
        assert_eq!(
            value("transport/unicast/open_timeout").as_deref(),
            Some("1000")
        );
        assert_eq!(
            value("transport/unicast/accept_timeout").as_deref(),
            Some("1000")
        );
        assert_eq!(
            value("listen/endpoints").as_deref(),
            Some(r#"["tcp/127.0.0.1:7447","udp/127.0.0.1:7447"]"#)
        );
    }

    #[test]
    fn a_client_keeps_trying_its_router_when_it_opens() {
        let client = NetworkOptions {
            connect: vec!["quic/10.0.0.1:7447".to_owned()],
            mode: Some("client".to_owned()),
            ..NetworkOptions::default()
        };
        let entries = client.config_entries();
        assert!(
            entries
                .iter()
                .any(|(k, v)| *k == "connect/timeout_ms" && *v == "10000")
        );
        assert!(
            !NetworkOptions::device_default()
                .config_entries()
                .iter()
                .any(|(k, _)| *k == "connect/timeout_ms"),
            "a peer keeps zenoh's default"
        );
    }

    fn lab_files() -> crate::security::TlsFiles {
        crate::security::TlsFiles {
            ca: "ca.pem".into(),
            cert: "c.pem".into(),
            key: "k.pem".into(),
        }
    }

    #[test]
    fn a_secured_role_speaks_quic_with_mixed_reliability_and_nothing_else() {
        let device = NetworkOptions::device_default().secured(lab_files());
        assert_eq!(device.connect, vec!["quic/127.0.0.1:7447".to_owned()]);
        let entries = device.config_entries();
        let value = |key: &str| {
            entries
                .iter()
                .find(|(k, _)| *k == key)
                .map(|(_, v)| v.clone())
        };
        assert_eq!(
            value("connect/endpoints").as_deref(),
            Some(r#"["quic/127.0.0.1:7447?mixed_rel=1"]"#)
        );
        assert_eq!(
            value("transport/link/protocols").as_deref(),
            Some(r#"["quic"]"#)
        );
        let server = NetworkOptions::server_default().secured(lab_files());
        let entries = server.config_entries();
        assert!(
            entries.iter().any(|(k, v)| *k == "listen/endpoints"
                && v == r#"["quic/127.0.0.1:7447?mixed_rel=auto"]"#)
        );
        // Metadata and config already on the endpoint are kept; an explicit choice is not overridden.
        assert_eq!(
            secure_endpoint("quic/h:1?iface=lo#bind=x", true, "1"),
            "quic/h:1?iface=lo;mixed_rel=1#bind=x"
        );
        assert_eq!(
            secure_endpoint("quic/h:1?mixed_rel=0", true, "1"),
            "quic/h:1?mixed_rel=0"
        );
        assert_eq!(secure_endpoint("quic/h:1", false, "1"), "quic/h:1");
    }

    #[test]
    fn a_tls_or_plain_endpoint_with_certificates_is_refused_with_the_reason() {
        let mut options = NetworkOptions::device_default().secured(lab_files());
        options.connect = vec!["tls/127.0.0.1:7447".to_owned()];
        let err = options.check().unwrap_err();
        assert!(
            err.contains("quic/HOST:PORT") && err.contains("#2557"),
            "{err}"
        );
        options.connect = vec!["tcp/127.0.0.1:7447".to_owned()];
        let err = options.check().unwrap_err();
        assert!(err.contains("bypass"), "{err}");
        let plain = NetworkOptions {
            connect: vec!["quic/127.0.0.1:7447".to_owned()],
            ..NetworkOptions::default()
        };
        assert!(plain.check().unwrap_err().contains("needs --tls-ca"));
    }
}
