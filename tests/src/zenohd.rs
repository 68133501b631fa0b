//! zenoh's own router (`zenohd` 1.10.2) for the tests that run a site's backbone: where its binary is, and the
//! `--tls-*` flags a role process is given for its certificate.
//!
//! Owns: [`zenohd_binary`], [`tls_args`]. Must not: start or stop processes (the tests do, on loopback or in a
//! [`crate::netns::NetnsLab`]).

use std::path::PathBuf;

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
