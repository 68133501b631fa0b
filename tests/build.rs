//! Build script of the test lab: sets `cfg(netns_lab)` when this machine can run the network-namespace lab
//! (root, and a working `ip netns`), so the lab's tests show as ignored, with the reason, where it cannot.

use std::process::Command;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(netns_lab)");
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
}
