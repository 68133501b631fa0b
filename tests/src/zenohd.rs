//! zenoh's own router (`zenohd` 1.10.2) for the tests and benches that run a site's backbone: where its binary
//! is, starting it on loopback (plain, or with a lab's configuration), and the `--tls-*` flags a role process
//! is given for its certificate.
//!
//! Owns: [`zenohd_binary`], [`start_plain_router`], [`start_lab_router`], [`tls_args`]. Must not: start
//! routers inside a [`crate::netns::NetnsLab`] (its tests place them in their namespaces themselves).

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Duration;

use anyhow::{Context, Result, bail};

use sinew_protocol::security::TlsFiles;

/// The `zenohd` binary: on PATH, else cargo's install directory. Panics with the install command when it is
/// in neither (`.ci/run` installs it).
pub fn zenohd_binary() -> PathBuf {
    let on_path = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|dir| dir.join("zenohd"))
            .find(|p| p.is_file())
    });
    let in_cargo = std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo")))
        .map(|home| home.join("bin/zenohd"))
        .filter(|p| p.is_file());
    on_path.or(in_cargo).unwrap_or_else(|| {
        panic!(
            "zenohd is not installed: `cargo install zenohd --version 1.10.2 --locked` (.ci/run installs it)"
        )
    })
}

/// The `--tls-ca`, `--tls-cert` and `--tls-key` flags of a role with certificate `files`.
pub fn tls_args(files: &TlsFiles) -> Vec<String> {
    [
        ("--tls-ca", &files.ca),
        ("--tls-cert", &files.cert),
        ("--tls-key", &files.key),
    ]
    .into_iter()
    .flat_map(|(flag, path)| [flag.to_owned(), path.display().to_string()])
    .collect()
}

/// `zenohd` listening on `endpoint` (TCP on loopback), no multicast scouting; returned once it accepts
/// connections (a client's session opened before then fails). Killed when dropped.
pub fn start_plain_router(endpoint: &str) -> Result<crate::harness::KillOnDrop> {
    let router = crate::harness::KillOnDrop(
        Command::new(zenohd_binary())
            .args(["--listen", endpoint, "--no-multicast-scouting"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .context("starting zenohd")?,
    );
    let address = endpoint
        .strip_prefix("tcp/")
        .with_context(|| format!("{endpoint} is not a tcp/ endpoint"))?;
    if !crate::harness::wait_until(Duration::from_secs(10), || {
        std::net::TcpStream::connect(address).is_ok()
    }) {
        bail!("zenohd never listened on {endpoint}");
    }
    Ok(router)
}

/// The lab's `zenohd`: the configuration `sinew certs` writes (`write_router_config`: mode router, listening on
/// `endpoint` with QUIC's mixed reliability, mutual TLS with the lab's `router` certificate, QUIC only, the
/// lab's access rules for every scene in it), loaded with `zenohd -c`. Killed when dropped.
pub fn start_lab_router(
    certs: &sinew::certs::LabCerts,
    endpoint: &str,
) -> Result<crate::harness::KillOnDrop> {
    let config = sinew::certs::write_router_config(&certs.dir, &[endpoint.to_owned()])?;
    let router = crate::harness::KillOnDrop(
        Command::new(zenohd_binary())
            .arg("-c")
            .arg(&config)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .context("starting zenohd")?,
    );
    // QUIC is UDP: wait until the router's process is up and has bound its port (a UDP bind on it fails).
    let address = endpoint
        .strip_prefix("quic/")
        .with_context(|| format!("{endpoint} is not a quic/ endpoint"))?;
    if !crate::harness::wait_until(Duration::from_secs(10), || {
        std::net::UdpSocket::bind(address).is_err()
    }) {
        bail!(
            "zenohd never bound {endpoint} (its config: {})",
            config.display()
        );
    }
    Ok(router)
}
