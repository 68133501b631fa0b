//! Command-line flags every role shares (behind the `cli` feature, so the wire crate stays plain data for
//! anyone who links it without clap).
//!
//! Owns: the `--emulate-*` flags, which turn into an [`EmulationConfig`] on what the role publishes (a
//! server's force commands, a hapticserver's poses), and the zenoh flags ([`NetworkArgs`]), which turn into
//! [`NetworkOptions`] over the role's defaults.

use crate::network::NetworkOptions;
use crate::rt::EmulationConfig;

/// `--connect`, `--listen`, `--zenoh-config`, `--zenoh-mode`: `#[command(flatten)]` them into a role's arguments.
#[derive(Debug, Clone, PartialEq, Eq, Default, clap::Args)]
pub struct NetworkArgs {
    /// zenoh endpoint to connect to (repeatable) [default, unless --zenoh-config is given: a device connects to
    /// the server's TCP and UDP endpoints at 127.0.0.1:7447, a viewer or recorder to the TCP one, a server to none].
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// zenoh endpoint to listen on (repeatable) [default, unless --zenoh-config is given or --zenoh-mode is
    /// client: a server listens on tcp/127.0.0.1:7447 and udp/127.0.0.1:7447 (devices get one transport with two
    /// links: reliable messages on TCP, poses and forces on UDP), the other roles on none].
    #[arg(long, value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// zenoh config file (JSON5), loaded first; --connect, --listen and --zenoh-mode override it.
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<std::path::PathBuf>,
    /// zenoh mode: peer (default) or client (through a zenohd router).
    #[arg(long, value_name = "MODE")]
    pub zenoh_mode: Option<String>,
    /// The lab's CA certificate (PEM, from `sinew certs`): with --tls-cert and --tls-key, every link is mutual
    /// TLS (over QUIC) and default endpoints become quic/ ones (a server then enforces the roles' access rules).
    #[arg(long, value_name = "FILE", requires_all = ["tls_cert", "tls_key"])]
    pub tls_ca: Option<std::path::PathBuf>,
    /// This role's certificate (PEM); its common name is the role and scene: server@<scene>, observer@<scene> or
    /// device-<id>@<scene> (`sinew certs` issues them).
    #[arg(long, value_name = "FILE", requires_all = ["tls_ca", "tls_key"])]
    pub tls_cert: Option<std::path::PathBuf>,
    /// This role's private key (PEM).
    #[arg(long, value_name = "FILE", requires_all = ["tls_ca", "tls_cert"])]
    pub tls_key: Option<std::path::PathBuf>,
}

impl NetworkArgs {
    /// The options these flags ask for: each endpoint list as given, or else the role's default (none when a
    /// config file is given, whose endpoints then apply).
    pub fn options(&self, role_default: NetworkOptions) -> NetworkOptions {
        let with_file = self.zenoh_config.is_some();
        let pick = |given: &[String], default: Vec<String>| {
            if !given.is_empty() {
                given.to_vec()
            } else if with_file {
                Vec::new()
            } else {
                default
            }
        };
        let role_default = match self.tls_files() {
            Some(tls) => role_default.secured(tls),
            None => role_default,
        };
        // A client of a router is reached through the router: it listens on nothing unless told to (a server
        // listening on its default port beside another scene's server on the same host could not bind it).
        let default_listen = if self.zenoh_mode.as_deref() == Some("client") {
            Vec::new()
        } else {
            role_default.listen
        };
        NetworkOptions {
            config_file: self.zenoh_config.clone(),
            listen: pick(&self.listen, default_listen),
            connect: pick(&self.connect, role_default.connect),
            mode: self.zenoh_mode.clone(),
            tls: role_default.tls,
            access_control: None,
        }
    }

    /// The TLS files, when all three flags are given (clap requires all or none).
    pub fn tls_files(&self) -> Option<crate::security::TlsFiles> {
        Some(crate::security::TlsFiles {
            ca: self.tls_ca.clone()?,
            cert: self.tls_cert.clone()?,
            key: self.tls_key.clone()?,
        })
    }
}

/// `--emulate-delay-ms`, `--emulate-jitter-ms`, `--emulate-loss`, `--emulate-seed`: `#[command(flatten)]` them
/// into a role's arguments.
#[derive(Debug, Clone, Copy, PartialEq, clap::Args)]
pub struct EmulationArgs {
    /// Emulate a distant site: delay every message this role publishes on the haptic path (a server's force
    /// commands, a hapticserver's poses) by this much, ms.
    #[arg(long, default_value_t = 0.0)]
    pub emulate_delay_ms: f64,
    /// Vary each emulated delay uniformly by up to this much either way, ms (order is kept).
    #[arg(long, default_value_t = 0.0)]
    pub emulate_jitter_ms: f64,
    /// Lose this fraction of those messages (0..1), seeded by --emulate-seed.
    #[arg(long, default_value_t = 0.0)]
    pub emulate_loss: f64,
    /// Seed of the emulated loss and jitter.
    #[arg(long, default_value_t = 1)]
    pub emulate_seed: u64,
}

impl EmulationArgs {
    /// The emulation these flags ask for, checked: a clear message for a negative delay, a loss outside 0..1,
    /// or a non-finite value.
    pub fn config(&self) -> Result<EmulationConfig, String> {
        let config = EmulationConfig {
            delay_ms: self.emulate_delay_ms,
            jitter_ms: self.emulate_jitter_ms,
            loss: self.emulate_loss,
            seed: self.emulate_seed,
        };
        config.validate().map(|()| config)
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Debug, Parser)]
    struct Role {
        #[command(flatten)]
        emulation: EmulationArgs,
    }

    #[derive(Debug, Parser)]
    struct Net {
        #[command(flatten)]
        network: NetworkArgs,
    }

    #[test]
    fn network_flags_override_the_role_default_and_a_config_file_replaces_it() {
        let parse = |args: &[&str]| Net::try_parse_from(args).unwrap().network;
        let server = NetworkOptions::server_default;
        let bare = parse(&["role"]).options(server());
        assert_eq!(bare.listen, server().listen);
        assert!(bare.connect.is_empty() && bare.config_file.is_none() && bare.mode.is_none());
        let given = parse(&[
            "role",
            "--listen",
            "tcp/0.0.0.0:7447",
            "--connect",
            "tcp/r:7447",
        ])
        .options(server());
        assert_eq!(given.listen, vec!["tcp/0.0.0.0:7447"]);
        assert_eq!(given.connect, vec!["tcp/r:7447"]);
        // A server that is a router's client listens on nothing, unless told to.
        let client = parse(&["role", "--zenoh-mode", "client", "--connect", "tcp/r:7447"]);
        assert!(client.options(server()).listen.is_empty());
        let told = parse(&[
            "role",
            "--zenoh-mode",
            "client",
            "--listen",
            "tcp/0.0.0.0:7448",
        ]);
        assert_eq!(told.options(server()).listen, vec!["tcp/0.0.0.0:7448"]);
        let file = parse(&[
            "role",
            "--zenoh-config",
            "z.json5",
            "--zenoh-mode",
            "client",
        ])
        .options(NetworkOptions::device_default());
        assert!(file.listen.is_empty() && file.connect.is_empty());
        assert_eq!(file.mode.as_deref(), Some("client"));
        assert_eq!(
            parse(&["role"])
                .options(NetworkOptions::device_default())
                .connect,
            NetworkOptions::device_default().connect
        );
    }

    #[test]
    fn flags_become_a_checked_emulation() {
        let role = Role::try_parse_from([
            "role",
            "--emulate-delay-ms",
            "50",
            "--emulate-jitter-ms",
            "10",
            "--emulate-loss",
            "0.05",
            "--emulate-seed",
            "7",
        ])
        .unwrap();
        let config = role.emulation.config().unwrap();
        assert_eq!(
            config,
            EmulationConfig {
                delay_ms: 50.0,
                jitter_ms: 10.0,
                loss: 0.05,
                seed: 7
            }
        );
        let off = Role::try_parse_from(["role"]).unwrap();
        assert!(off.emulation.config().unwrap().is_off());
        let bad = Role::try_parse_from(["role", "--emulate-loss", "1.5"]).unwrap();
        assert!(bad.emulation.config().unwrap_err().contains("loss"));
    }
}
