//! Sessions only the invited can join: TLS files, role names and the access-control rules, as plain data.
//!
//! Owns: [`TlsFiles`] (a role's CA, certificate and key), [`RoleName`] (the certificate common name that says
//! who a peer is: `server`, `observer`, `device-<id>` or a site's `router`) and [`access_control_json5`], the rules a server
//! enforces on what reaches it. Identity comes from TLS client certificates (mutual TLS), not zenoh's
//! user/password: a certificate proves the peer holds a key the lab's CA signed, its common name is the role
//! zenoh's access control matches exactly, and the same files also encrypt the link. A password would travel
//! in each role's config and identify nothing the link itself does not.
//!
//! The rules (default deny, enforced on what arrives at the server):
//! - every peer with a lab certificate may read the scene (subscribe, query, liveliness) and may be sent
//!   everything the server publishes;
//! - `device-<id>` may publish only its own pose, hello and presence token;
//! - `observer` may publish only a viewer's hello and presence token: never a pose;
//! - `server` may do anything (a second server for the scene must still be noticed and refused);
//! - `router`, a site's `zenohd`, may do what the server may, and is sent everything: behind it a server sees
//!   every message arrive under the router's certificate and sends everything to it, and the router holds each
//!   client to these same rules (its `zenohd.json5`). With the router only granted the server's rule, the
//!   server's sending to it was refused (it is not otherwise in the lab) and no hand felt the pad.
//!
//! Must not: open sessions or read certificates' contents (zenoh does, when a role opens its session).

use std::path::PathBuf;

use crate::keys::validate_segment;

/// A role's TLS files (PEM): the lab CA it trusts, its certificate, its private key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlsFiles {
    /// The lab's CA certificate.
    pub ca: PathBuf,
    /// This role's certificate (its common name is its role).
    pub cert: PathBuf,
    /// This role's private key.
    pub key: PathBuf,
}

impl TlsFiles {
    /// Each file exists and is readable; the error names the flag and the file.
    pub fn check(&self) -> Result<(), String> {
        for (flag, path) in [
            ("--tls-ca", &self.ca),
            ("--tls-cert", &self.cert),
            ("--tls-key", &self.key),
        ] {
            std::fs::File::open(path).map_err(|e| format!("{flag} {}: {e}", path.display()))?;
        }
        Ok(())
    }
}

/// Who a peer is, as its certificate's common name says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RoleName {
    /// The scene's server.
    Server,
    /// A viewer or recorder: watches, never touches.
    Observer,
    /// The hapticserver of one device id.
    Device(String),
    /// A site's `zenohd`, which every role is a client of (`sinew certs` writes its configuration): it holds
    /// each client to the rules below, and a server behind it lets through what it brings in.
    Router,
}

impl RoleName {
    /// The certificate common name: `server`, `observer`, `device-<id>` or `router`.
    pub fn common_name(&self) -> String {
        match self {
            RoleName::Server => "server".to_owned(),
            RoleName::Observer => "observer".to_owned(),
            RoleName::Device(id) => format!("device-{id}"),
            RoleName::Router => "router".to_owned(),
        }
    }

    /// A device id must be a valid key segment.
    pub fn check(&self) -> Result<(), String> {
        match self {
            RoleName::Device(id) => validate_segment("device id", id).map_err(|e| e.to_string()),
            _ => Ok(()),
        }
    }
}

/// Every message kind zenoh's access control knows.
const ALL_MESSAGES: &str = "[\"put\",\"delete\",\"declare_subscriber\",\"query\",\"declare_queryable\",\
\"reply\",\"liveliness_token\",\"declare_liveliness_subscriber\",\"liveliness_query\"]";

fn quoted(items: &[String]) -> String {
    let q: Vec<String> = items.iter().map(|s| format!("{s:?}")).collect();
    format!("[{}]", q.join(","))
}

/// The access-control section (JSON5, for zenoh's `access_control` key) a server of `scene` enforces, for the
/// devices `device_ids` its world binds. Ids must be valid key segments (the world loader checks them).
pub fn access_control_json5(scene: &str, device_ids: &[String]) -> String {
    let prefix = format!("sinew/{scene}");
    let mut rules = vec![
        format!(
            "{{id:\"egress\",messages:{ALL_MESSAGES},flows:[\"egress\"],permission:\"allow\",key_exprs:[\"**\"]}}"
        ),
        format!(
            "{{id:\"read-scene\",messages:[\"declare_subscriber\",\"query\",\"declare_liveliness_subscriber\",\
             \"liveliness_query\",\"reply\"],flows:[\"ingress\"],permission:\"allow\",key_exprs:[\"{prefix}/**\"]}}"
        ),
        format!(
            "{{id:\"server\",messages:{ALL_MESSAGES},flows:[\"ingress\"],permission:\"allow\",key_exprs:[\"**\"]}}"
        ),
        format!(
            "{{id:\"observer\",messages:[\"put\",\"liveliness_token\"],flows:[\"ingress\"],permission:\"allow\",\
             key_exprs:[\"{prefix}/hello/viewer/*\",\"{prefix}/presence/viewer/*\"]}}"
        ),
    ];
    let mut everyone = vec![
        RoleName::Server.common_name(),
        RoleName::Observer.common_name(),
        RoleName::Router.common_name(),
    ];
    let mut subjects = vec![
        "{id:\"server\",cert_common_names:[\"server\"]}".to_owned(),
        "{id:\"observer\",cert_common_names:[\"observer\"]}".to_owned(),
        "{id:\"router\",cert_common_names:[\"router\"]}".to_owned(),
    ];
    let mut policies = vec![
        "{rules:[\"server\"],subjects:[\"server\",\"router\"]}".to_owned(),
        "{rules:[\"observer\"],subjects:[\"observer\"]}".to_owned(),
    ];
    for id in device_ids {
        let name = RoleName::Device(id.clone()).common_name();
        rules.push(format!(
            "{{id:\"{name}\",messages:[\"put\",\"liveliness_token\"],flows:[\"ingress\"],permission:\"allow\",\
             key_exprs:[\"{prefix}/device/{id}/pose\",\"{prefix}/hello/haptic/{id}\",\"{prefix}/presence/haptic/{id}\"]}}"
        ));
        subjects.push(format!("{{id:\"{name}\",cert_common_names:[\"{name}\"]}}"));
        policies.push(format!("{{rules:[\"{name}\"],subjects:[\"{name}\"]}}"));
        everyone.push(name);
    }
    subjects.push(format!(
        "{{id:\"lab\",cert_common_names:{}}}",
        quoted(&everyone)
    ));
    policies.push("{rules:[\"egress\",\"read-scene\"],subjects:[\"lab\"]}".to_owned());
    format!(
        "{{enabled:true,default_permission:\"deny\",rules:[{}],subjects:[{}],policies:[{}]}}",
        rules.join(","),
        subjects.join(","),
        policies.join(",")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn role_names_are_the_common_names() {
        assert_eq!(RoleName::Server.common_name(), "server");
        assert_eq!(RoleName::Device("left".into()).common_name(), "device-left");
        assert!(RoleName::Device("a/b".into()).check().is_err());
    }

    #[test]
    fn the_rules_name_each_device_and_its_own_keys_only() {
        let acl = access_control_json5("pad", &["left".into(), "right".into()]);
        assert!(acl.contains("default_permission:\"deny\""));
        assert!(acl.contains("\"sinew/pad/device/left/pose\""));
        assert!(acl.contains("cert_common_names:[\"device-right\"]"));
        assert!(acl.contains(
            "cert_common_names:[\"server\",\"observer\",\"router\",\"device-left\",\"device-right\"]"
        ));
        // An observer's rule names no pose key.
        let observer = acl
            .split("{id:\"observer\",messages")
            .nth(1)
            .and_then(|s| s.split('}').next())
            .unwrap_or_default();
        assert!(!observer.contains("pose"), "{observer}");
    }

    #[test]
    fn missing_files_are_named() {
        let files = TlsFiles {
            ca: "/nonexistent/ca.pem".into(),
            cert: "/nonexistent/c.pem".into(),
            key: "/nonexistent/k.pem".into(),
        };
        let err = files.check().unwrap_err();
        assert!(err.starts_with("--tls-ca /nonexistent/ca.pem:"), "{err}");
    }
}
