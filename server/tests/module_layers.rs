//! The server crate's layers, checked from its source: every `crate::<module>` path outside a comment is an
//! arrow between top-level modules. ARCHITECTURE.md's layer table states these rules; this test holds them.
//! - No import circle between top-level modules.
//! - The engine (tissue, collision, interaction, haptics, multirate, sim, scene, training, replication,
//!   server_tick) never reads the world-file layer (`world`): the world file is one front end that produces
//!   the engine's descriptors.
//! - Pure state (replication, training, scene and the engine below them) never reaches the thread and I/O
//!   layers (`node`, `recording`).

#![allow(clippy::unwrap_used)] // test code: an unreadable source tree should panic loudly

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const ENGINE: [&str; 10] = [
    "tissue",
    "collision",
    "interaction",
    "haptics",
    "multirate",
    "sim",
    "scene",
    "training",
    "replication",
    "server_tick",
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Top-level module -> the top-level modules its code (not its comments) names as `crate::<module>`.
fn module_graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let modules: BTreeSet<String> = std::fs::read_dir(&src)
        .unwrap()
        .filter_map(|e| {
            let path = e.unwrap().path();
            let stem = path.file_stem()?.to_str()?.to_owned();
            (path.extension().is_some_and(|x| x == "rs") && stem != "lib" && stem != "main")
                .then_some(stem)
        })
        .collect();
    let mut graph = BTreeMap::new();
    for module in &modules {
        let mut files = vec![src.join(format!("{module}.rs"))];
        if src.join(module).is_dir() {
            rust_files(&src.join(module), &mut files);
        }
        let mut arrows = BTreeSet::new();
        for file in files {
            for line in std::fs::read_to_string(&file).unwrap().lines() {
                let code = line.split("//").next().unwrap_or("");
                for (at, _) in code.match_indices("crate::") {
                    let target: String = code[at + 7..]
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if &target != module && modules.contains(&target) {
                        arrows.insert(target);
                    }
                }
            }
        }
        graph.insert(module.clone(), arrows);
    }
    graph
}

#[test]
fn the_graph_sees_the_known_arrows() {
    // Sanity: a parser that saw nothing would pass every rule below.
    let graph = module_graph();
    assert!(graph["sim"].contains("tissue"), "{graph:?}");
    assert!(graph["world"].contains("scene"), "{graph:?}");
    assert!(graph["node"].contains("sim"), "{graph:?}");
    for module in ENGINE {
        assert!(graph.contains_key(module), "no module {module}: {graph:?}");
    }
}

#[test]
fn no_import_circle_between_modules() {
    let graph = module_graph();
    // Depth-first search with colours; report the first circle found as a path.
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        done: &mut BTreeSet<String>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|p| p == node) {
            let mut circle = path[at..].to_vec();
            circle.push(node.to_owned());
            return Some(circle);
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_owned());
        for next in &graph[node] {
            if let Some(circle) = visit(next, graph, done, path) {
                return Some(circle);
            }
        }
        path.pop();
        done.insert(node.to_owned());
        None
    }
    let mut done = BTreeSet::new();
    for module in graph.keys() {
        let circle = visit(module, &graph, &mut done, &mut Vec::new());
        assert!(
            circle.is_none(),
            "import circle: {}",
            circle.unwrap().join(" -> ")
        );
    }
}

#[test]
fn the_engine_never_reads_the_world_file_layer() {
    let graph = module_graph();
    for module in ENGINE {
        assert!(
            !graph[module].contains("world"),
            "{module} imports crate::world: the engine takes its own descriptors (scene, tissue::ObjectSpec, ...)"
        );
    }
}

#[test]
fn pure_state_never_reaches_the_thread_layer() {
    let graph = module_graph();
    for module in ENGINE {
        for layer in ["node", "recording"] {
            assert!(
                !graph[module].contains(layer),
                "{module} imports crate::{layer}: pure state must not depend on threads or I/O"
            );
        }
    }
}
