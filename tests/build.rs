//! Build script of the test lab: sets `cfg(netns_lab)` when this machine can run the network-namespace lab
//! (root, and a working `ip netns`), and `cfg(web_browser)` when it can drive the instructor's page in a
//! browser (chromium, node, `npm ci --prefix viewer/web`), so those tests show as ignored, with the reason,
//! where it cannot.

use std::process::Command;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(netns_lab)");
    println!("cargo::rustc-check-cfg=cfg(web_browser)");
    println!("cargo::rerun-if-changed=build.rs");
    let root = Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.trim_ascii() == b"0");
    let ip_netns = Command::new("ip")
        .args(["netns", "list"])
        .output()
        .is_ok_and(|o| o.status.success());
    if root && ip_netns {
        println!("cargo::rustc-cfg=netns_lab");
    }

    // The browser tests (tests/tests/web_browser.rs) need chromium, node, and the page's npm packages.
    let chromium = std::env::var_os("SINEW_CHROMIUM")
        .map_or("/usr/bin/chromium".into(), std::path::PathBuf::from);
    let packages = std::path::Path::new("../viewer/web/node_modules");
    for watched in [
        chromium.as_path(),
        &packages.join("playwright-core/package.json"),
        &packages.join("three/package.json"),
    ] {
        println!("cargo::rerun-if-changed={}", watched.display());
    }
    println!("cargo::rerun-if-env-changed=SINEW_CHROMIUM");
    let node = Command::new("node")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if node
        && chromium.is_file()
        && packages.join("playwright-core/package.json").is_file()
        && packages.join("three/package.json").is_file()
    {
        println!("cargo::rustc-cfg=web_browser");
    }
}
