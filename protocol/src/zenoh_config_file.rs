//! A zenoh configuration file (JSON5) from the `(key path, JSON5 value)` entries the roles insert into their own
//! configs ([`crate::network::NetworkOptions::config_entries`]), for a process that reads a file: `zenohd`.
//!
//! Owns: nesting the entries' `a/b/c` paths into objects ([`config_document`]) and a lab's router file
//! ([`lab_router_config`]: mode router, its listen endpoints, mutual TLS with its certificate, QUIC only, the
//! access rules of every scene it carries).
//!
//! Must not: parse or check the values (zenoh does, when the file is loaded: the tests load what this writes).

use crate::network::{LINK_LEASE_MS, NetworkOptions};
use crate::security::{SceneRoles, TlsFiles, router_access_control_json5};

/// One level of the document: each key's value, a JSON5 text or a nested level, in first-insertion order.
enum Node {
    Value(String),
    Object(Vec<(String, Node)>),
}

fn insert(level: &mut Vec<(String, Node)>, path: &[&str], value: &str) {
    let Some((first, rest)) = path.split_first() else {
        return;
    };
    let i = match level.iter().position(|(k, _)| k == first) {
        Some(i) => i,
        None => {
            level.push(((*first).to_owned(), Node::Object(Vec::new())));
            level.len() - 1
        }
    };
    let slot = &mut level[i].1;
    if rest.is_empty() {
        *slot = Node::Value(value.to_owned());
        return;
    }
    if let Node::Value(_) = slot {
        *slot = Node::Object(Vec::new());
    }
    if let Node::Object(children) = slot {
        insert(children, rest, value);
    }
}

fn write(level: &[(String, Node)], indent: usize, out: &mut String) {
    out.push_str("{\n");
    for (key, node) in level {
        out.push_str(&"  ".repeat(indent + 1));
        out.push_str(key);
        out.push_str(": ");
        match node {
            Node::Value(v) => out.push_str(v),
            Node::Object(children) => write(children, indent + 1, out),
        }
        out.push_str(",\n");
    }
    out.push_str(&"  ".repeat(indent));
    out.push('}');
}

/// A JSON5 document holding `entries` (`("transport/link/tls/enable_mtls", "true")` nests as
/// `transport: { link: { tls: { enable_mtls: true } } }`); a later entry for the same path replaces the earlier.
pub fn config_document(entries: &[(&str, String)]) -> String {
    let mut root = Vec::new();
    for (key, value) in entries {
        let path: Vec<&str> = key.split('/').filter(|s| !s.is_empty()).collect();
        insert(&mut root, &path, value);
    }
    let mut out = String::new();
    write(&root, 0, &mut out);
    out.push('\n');
    out
}

/// A lab's `zenohd` configuration: a router listening on `listen` (QUIC endpoints: mixed reliability is added),
/// mutual TLS with `tls` (the router's certificate), QUIC only, multicast scouting off, and the access rules of
/// every scene in `scenes` enforced on what each client's link brings in and is sent (by its certificate's
/// common name), as a server enforces its scene's when it is the router itself.
pub fn lab_router_config(listen: &[String], tls: &TlsFiles, scenes: &[SceneRoles]) -> String {
    let options = NetworkOptions {
        listen: listen.to_vec(),
        mode: Some("router".to_owned()),
        tls: Some(tls.clone()),
        access_control: Some(router_access_control_json5(scenes)),
        ..NetworkOptions::default()
    };
    let mut entries = options.config_entries();
    // The router's lease: every role drops its session with a router that died silently this long after (a
    // killed `zenohd` sends nothing on its QUIC links), and only then dials it again. With zenoh's 10 s
    // default, roles stayed on a dead router's session 6 s past its restart (`zenohd_sites.rs`).
    entries.push(("transport/link/tx/lease", LINK_LEASE_MS.to_string()));
    config_document(&entries)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_nest_into_objects_in_first_insertion_order_and_a_later_entry_replaces() {
        let doc = config_document(&[
            ("mode", "\"router\"".to_owned()),
            ("transport/link/tls/enable_mtls", "true".to_owned()),
            ("transport/unicast/max_links", "2".to_owned()),
            ("transport/link/protocols", "[\"quic\"]".to_owned()),
            ("mode", "\"client\"".to_owned()),
        ]);
        assert_eq!(
            doc,
            "{\n  mode: \"client\",\n  transport: {\n    link: {\n      tls: {\n        enable_mtls: true,\n      },\n      \
             protocols: [\"quic\"],\n    },\n    unicast: {\n      max_links: 2,\n    },\n  },\n}\n"
        );
    }

    #[test]
    fn a_lab_router_listens_on_quic_with_mutual_tls_and_the_scenes_rules() {
        let tls = TlsFiles {
            ca: "/lab/ca.pem".into(),
            cert: "/lab/router.pem".into(),
            key: "/lab/router-key.pem".into(),
        };
        let doc = lab_router_config(
            &["quic/0.0.0.0:7447".to_owned()],
            &tls,
            &[SceneRoles {
                scene: "pad".into(),
                device_ids: vec!["left".into()],
            }],
        );
        for part in [
            "mode: \"router\"",
            "\"quic/0.0.0.0:7447?mixed_rel=auto\"",
            "listen_certificate: \"/lab/router.pem\"",
            "enable_mtls: true",
            "protocols: [\"quic\"]",
            "access_control: {enabled:true,default_permission:\"deny\"",
            "\"sinew/pad/device/left/pose\"",
            "lease: 3000",
        ] {
            assert!(doc.contains(part), "{part} not in\n{doc}");
        }
    }
}
