//! Sessions only the invited can join: TLS files, role names and the access-control rules, as plain data.
//!
//! Owns: [`TlsFiles`] (a role's CA, certificate and key), [`RoleName`] (the certificate common name that says
//! who a peer is and for which scene: `server@<scene>`, `observer@<scene>`, `device-<id>@<scene>`, or a site's
//! `router`), [`access_control_json5`] (the rules a server enforces on what reaches it) and
//! [`router_access_control_json5`] (the rules a site's router enforces for every scene it carries). Identity
//! comes from TLS client certificates (mutual TLS), not zenoh's user/password: a certificate proves the peer
//! holds a key the lab's CA signed, its common name is the role zenoh's access control matches exactly, and the
//! same files also encrypt the link. A password would travel in each role's config and identify nothing the
//! link itself does not.
//!
//! The rules of a scene (default deny; every key is under `sinew/<scene>`, and no rule grants anything outside
//! it, so a role of one scene can neither touch nor read another on a shared router):
//! - every role of the scene may read it (subscribe, query, liveliness) and may be sent everything in it;
//! - `device-<id>@<scene>` may publish only its own pose, hello and presence token;
//! - `observer@<scene>` may publish only a viewer's hello and presence token: never a pose;
//! - `server@<scene>` may do anything in the scene (a second server for it must still be noticed and refused);
//! - at a server, `router` (a site's `zenohd`) may do what the server may, and is sent everything of the
//!   scene: behind it a server sees every message arrive under the router's certificate, and the router holds
//!   each client to these same rules (its `zenohd.json5`). With the router only granted the server's rule, the
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
    /// each client to the rules below, and a server behind it lets through what it brings in. One per site,
    /// whatever scenes it carries.
    Router,
}

impl RoleName {
    /// The certificate common name of this role in `scene`: `server@<scene>`, `observer@<scene>`,
    /// `device-<id>@<scene>`, or `router` (the site's, for every scene). The scene is in the name so that one
    /// router can carry several scenes and hold each role to its own: an observer of one scene presents a
    /// name the rules of another do not know.
    pub fn common_name(&self, scene: &str) -> String {
        match self {
            RoleName::Server => format!("server@{scene}"),
            RoleName::Observer => format!("observer@{scene}"),
            RoleName::Device(id) => format!("device-{id}@{scene}"),
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

/// One scene a router carries: its name and the device ids its world binds (each a valid key segment).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SceneRoles {
    /// The scene (a key segment).
    pub scene: String,
    /// Its devices' ids.
    pub device_ids: Vec<String>,
}

/// Every message kind zenoh's access control knows.
const ALL_MESSAGES: &str = "[\"put\",\"delete\",\"declare_subscriber\",\"query\",\"declare_queryable\",\
\"reply\",\"liveliness_token\",\"declare_liveliness_subscriber\",\"liveliness_query\"]";

fn quoted(items: &[String]) -> String {
    let q: Vec<String> = items.iter().map(|s| format!("{s:?}")).collect();
    format!("[{}]", q.join(","))
}

/// An access-control section under construction: rules, subjects and policies as JSON5 objects.
#[derive(Default)]
struct Acl {
    rules: Vec<String>,
    subjects: Vec<String>,
    policies: Vec<String>,
}

impl Acl {
    fn subject(&mut self, id: &str, names: &[String]) {
        self.subjects.push(format!(
            "{{id:\"{id}\",cert_common_names:{}}}",
            quoted(names)
        ));
    }

    fn rule(&mut self, id: &str, messages: &str, flow: &str, key_exprs: &[String]) {
        self.rules.push(format!(
            "{{id:\"{id}\",messages:{messages},flows:[\"{flow}\"],permission:\"allow\",key_exprs:{}}}",
            quoted(key_exprs)
        ));
    }

    fn policy(&mut self, rules: &[&str], subjects: &[&str]) {
        let own =
            |items: &[&str]| quoted(&items.iter().map(|s| (*s).to_owned()).collect::<Vec<_>>());
        self.policies.push(format!(
            "{{rules:{},subjects:{}}}",
            own(rules),
            own(subjects)
        ));
    }

    /// The rules of one scene: everything under `sinew/<scene>` and nothing else. Its server (and, when
    /// `router_behind` is set, the site's router, through which everything of the scene arrives) may do
    /// anything in it; its observer may only say hello and be present; each device may only publish its own
    /// pose, hello and presence; every one of them may read the scene and be sent what is in it.
    fn scene(&mut self, scene: &SceneRoles, router_behind: bool) {
        let prefix = format!("sinew/{}", scene.scene);
        let everything = [format!("{prefix}/**")];
        let name = |role: RoleName| role.common_name(&scene.scene);
        let id = |what: &str| format!("{what}@{}", scene.scene);
        let (server, observer, router) = (
            name(RoleName::Server),
            name(RoleName::Observer),
            name(RoleName::Router),
        );
        let mut members = vec![server.clone(), observer.clone()];
        if router_behind {
            members.push(router.clone());
        }
        self.rule(&id("egress"), ALL_MESSAGES, "egress", &everything);
        self.rule(
            &id("read"),
            "[\"declare_subscriber\",\"query\",\"declare_liveliness_subscriber\",\"liveliness_query\",\"reply\"]",
            "ingress",
            &everything,
        );
        self.rule(&id("server"), ALL_MESSAGES, "ingress", &everything);
        self.rule(
            &id("observer"),
            "[\"put\",\"liveliness_token\"]",
            "ingress",
            &[
                format!("{prefix}/hello/viewer/*"),
                format!("{prefix}/presence/viewer/*"),
            ],
        );
        self.subject(&server, std::slice::from_ref(&server));
        self.subject(&observer, std::slice::from_ref(&observer));
        let mut server_subjects = vec![server.as_str()];
        if router_behind {
            self.subject(&router, std::slice::from_ref(&router));
            server_subjects.push(router.as_str());
        }
        self.policy(&[&id("server")], &server_subjects);
        self.policy(&[&id("observer")], &[&observer]);
        for device in &scene.device_ids {
            let device_name = name(RoleName::Device(device.clone()));
            self.rule(
                &device_name,
                "[\"put\",\"liveliness_token\"]",
                "ingress",
                &[
                    format!("{prefix}/device/{device}/pose"),
                    format!("{prefix}/hello/haptic/{device}"),
                    format!("{prefix}/presence/haptic/{device}"),
                ],
            );
            self.subject(&device_name, std::slice::from_ref(&device_name));
            self.policy(&[&device_name], &[&device_name]);
            members.push(device_name);
        }
        let lab = id("lab");
        self.subject(&lab, &members);
        self.policy(&[&id("egress"), &id("read")], &[&lab]);
    }

    fn json5(&self) -> String {
        format!(
            "{{enabled:true,default_permission:\"deny\",rules:[{}],subjects:[{}],policies:[{}]}}",
            self.rules.join(","),
            self.subjects.join(","),
            self.policies.join(",")
        )
    }
}

/// The access-control section (JSON5, for zenoh's `access_control` key) a server of `scene` enforces, for the
/// devices `device_ids` its world binds. Ids must be valid key segments (the world loader checks them).
pub fn access_control_json5(scene: &str, device_ids: &[String]) -> String {
    let mut acl = Acl::default();
    acl.scene(
        &SceneRoles {
            scene: scene.to_owned(),
            device_ids: device_ids.to_vec(),
        },
        true,
    );
    acl.json5()
}

/// The access-control section a site's router enforces for every scene it carries: each scene's roles held
/// to that scene's rules and keys, so nothing of one scene reaches a role of another.
pub fn router_access_control_json5(scenes: &[SceneRoles]) -> String {
    let mut acl = Acl::default();
    for scene in scenes {
        acl.scene(scene, false);
    }
    acl.json5()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn role_names_are_the_common_names_in_their_scene() {
        assert_eq!(RoleName::Server.common_name("pad"), "server@pad");
        assert_eq!(
            RoleName::Device("left".into()).common_name("pad"),
            "device-left@pad"
        );
        assert_eq!(RoleName::Router.common_name("pad"), "router");
        assert!(RoleName::Device("a/b".into()).check().is_err());
    }

    /// The body of the rule with id `id` (up to its closing brace).
    fn rule<'a>(acl: &'a str, id: &str) -> &'a str {
        acl.split(&format!("{{id:\"{id}\",messages"))
            .nth(1)
            .and_then(|s| s.split('}').next())
            .unwrap_or_default()
    }

    #[test]
    fn the_rules_name_each_device_and_its_own_keys_only() {
        let acl = access_control_json5("pad", &["left".into(), "right".into()]);
        assert!(acl.contains("default_permission:\"deny\""));
        assert!(rule(&acl, "device-left@pad").contains("\"sinew/pad/device/left/pose\""));
        assert!(!rule(&acl, "device-left@pad").contains("right"));
        assert!(acl.contains("cert_common_names:[\"device-right@pad\"]"));
        assert!(acl.contains(
            "{id:\"lab@pad\",cert_common_names:[\"server@pad\",\"observer@pad\",\"router\",\"device-left@pad\",\"device-right@pad\"]}"
        ));
        // An observer's rule names no pose key.
        let observer = rule(&acl, "observer@pad");
        assert!(
            !observer.is_empty() && !observer.contains("pose"),
            "{observer}"
        );
    }

    #[test]
    fn a_routers_rules_keep_each_scenes_roles_in_their_scene() {
        let acl = router_access_control_json5(&[
            SceneRoles {
                scene: "pad".into(),
                device_ids: vec!["left".into()],
            },
            SceneRoles {
                scene: "cautery".into(),
                device_ids: vec!["left".into()],
            },
        ]);
        for scene in ["pad", "cautery"] {
            let prefix = format!("\"sinew/{scene}/");
            for id in ["egress", "read", "server", "observer", "device-left"] {
                let body = rule(&acl, &format!("{id}@{scene}"));
                let keys = body.split("key_exprs:").nth(1).unwrap_or_default();
                assert!(!keys.is_empty(), "{id}@{scene} has no rule");
                // Every key the rule grants is under its own scene.
                for key in keys.trim_matches(|c| c == '[' || c == ']').split(',') {
                    assert!(key.starts_with(&prefix), "{id}@{scene} grants {key}");
                }
            }
            assert!(acl.contains(&format!(
                "{{rules:[\"egress@{scene}\",\"read@{scene}\"],subjects:[\"lab@{scene}\"]}}"
            )));
        }
        // The router is no subject of its own rules: it is the one enforcing them.
        assert!(!acl.contains("\"router\""), "{acl}");
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
