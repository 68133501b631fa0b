#!/usr/bin/env bash
# The README's test command: install what the tests need on a fresh Debian/Ubuntu machine, then run them all.
# `.ci/run` calls exactly this after its style, lint and dependency checks.
set -euo pipefail
cd "$(dirname "$0")/.."

as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; elif command -v sudo >/dev/null 2>&1; then sudo "$@"; else
  echo "tests/run.sh: not root and no sudo: install by hand: $*" >&2; return 1; fi; }

# The viewer's offscreen PNG tests render on Mesa's lavapipe (software Vulkan): no GPU, no X server.
# The network-namespace lab (tests/tests/netns_lab.rs, as root) needs iproute2 and ping.
# `sinew report`'s figures (tests/tests/recording.rs) label with DejaVu Sans.
packages=(libvulkan1 mesa-vulkan-drivers iproute2 iputils-ping fonts-dejavu-core)
if ! dpkg -s "${packages[@]}" >/dev/null 2>&1; then
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${packages[@]}" >/dev/null
fi
# The Python client's tests (tests/tests/python_client.rs) run protocol/python against a real server.
if ! python3 -c "import zenoh" >/dev/null 2>&1; then
  if ! command -v python3 >/dev/null 2>&1 || ! python3 -m pip --version >/dev/null 2>&1; then
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3 python3-pip >/dev/null
  fi
  python3 -m pip install --quiet "eclipse-zenoh==1.10.2" 2>/dev/null \
    || python3 -m pip install --quiet --break-system-packages "eclipse-zenoh==1.10.2"
fi
# zenoh's own router, for the backbone test (tests/tests/zenohd_backbone.rs): a crate on the registry, built
# once into cargo's bin directory (about 5 minutes on 2 cores).
if ! command -v zenohd >/dev/null 2>&1 && [ ! -x "${CARGO_HOME:-$HOME/.cargo}/bin/zenohd" ]; then
  cargo install zenohd --version 1.10.2 --locked --quiet
fi
# The instructor's page (tests/tests/web_browser.rs): Debian's chromium, node and npm, then the page's packages
# (three.js, and playwright-core to drive chromium) exactly as viewer/web/package-lock.json pins them.
if ! dpkg -s chromium >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  web_packages=(chromium)
  command -v npm >/dev/null 2>&1 || web_packages+=(nodejs npm)
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${web_packages[@]}" >/dev/null
fi
if ! cmp -s viewer/web/package-lock.json viewer/web/node_modules/.sinew-installed-lock.json; then
  npm ci --prefix viewer/web --no-audit --no-fund --loglevel=error
  cp viewer/web/package-lock.json viewer/web/node_modules/.sinew-installed-lock.json
fi
# Mesa wants a runtime dir (else it prints a harmless error per render).
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/xdg-runtime-$(id -u)}"
mkdir -p "$XDG_RUNTIME_DIR" && chmod 700 "$XDG_RUNTIME_DIR"

echo "== loom: every interleaving of the worker pool's hand-off (sinew-parallel under --cfg loom, own target dir)"
RUSTFLAGS="--cfg loom" cargo test -p sinew-parallel --release --target-dir target/loom --lib board

echo "== tests: cargo test --workspace --release"
cargo test --workspace --release
