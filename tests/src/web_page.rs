//! The instructor's page in a real browser, for the browser tests: a `sinew-web` process, and headless
//! chromium driven by playwright-core (`viewer/web/tools/page_driver.mjs`) that answers what the page has
//! replicated (`window.sinew`) and takes screenshots.
//!
//! Owns: starting and stopping both, reading the gateway's address from its first line, and the checks of a
//! screenshot's pixels. Both processes are killed when their handles drop, however a test ends.
//!
//! Needs: Debian's chromium (`/usr/bin/chromium`, or `SINEW_CHROMIUM`), node, and `npm ci --prefix
//! viewer/web` (three.js and playwright-core); `tests/run.sh` installs all three. The build script sets
//! `cfg(web_browser)` when they are there, so the browser tests show as ignored where they are not.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use anyhow::{Context, Result, anyhow, bail};
use serde_json::Value;

use crate::harness::KillOnDrop;
use crate::netns::role_binary;

/// `viewer/web` in this source tree.
pub fn web_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../viewer/web")
}

/// Lines of a child's stdout, read on a thread so a wait can time out.
struct Lines(mpsc::Receiver<String>);

impl Lines {
    fn of(stdout: impl std::io::Read + Send + 'static) -> Self {
        let (send, receive) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if send.send(line).is_err() {
                    return;
                }
            }
        });
        Self(receive)
    }

    fn next(&self, timeout: Duration) -> Result<String> {
        self.0
            .recv_timeout(timeout)
            .map_err(|e| anyhow!("no line within {timeout:?}: {e}"))
    }
}

/// A running `sinew-web` process.
pub struct WebGatewayProcess {
    _child: KillOnDrop,
    /// The page's address, `http://127.0.0.1:<port>/`.
    pub url: String,
}

impl WebGatewayProcess {
    /// Start `sinew-web` for `scene`, connecting to `connect` (zenoh endpoints), on a free port; `extra` goes
    /// on its command line. Returns once it printed its address.
    pub fn start(scene: &str, connect: &[String], extra: &[&str]) -> Result<Self> {
        Self::start_on(scene, connect, "127.0.0.1:0", extra)
    }

    /// [`Self::start`] on `http` (`ADDR:PORT`): a restarted gateway on the same port as before.
    pub fn start_on(scene: &str, connect: &[String], http: &str, extra: &[&str]) -> Result<Self> {
        let mut command = Command::new(role_binary("sinew-web")?);
        command
            .args(["--scene", scene, "--http", http])
            .args(connect.iter().flat_map(|e| ["--connect", e.as_str()]))
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        let mut child = command.spawn().context("starting sinew-web")?;
        let stdout = child.stdout.take().context("sinew-web's stdout")?;
        let child = KillOnDrop(child);
        let lines = Lines::of(stdout);
        let line = lines
            .next(Duration::from_secs(20))
            .context("sinew-web never said where it serves")?;
        let url = line
            .split_once(" at ")
            .map(|(_, url)| url.trim().to_owned())
            .with_context(|| format!("sinew-web's first line has no address: {line}"))?;
        Ok(Self { _child: child, url })
    }

    /// The gateway's counters (`/stats.json`), fetched with the page driver's node.
    pub fn stats(&self) -> Result<Value> {
        let script = format!(
            "fetch('{}stats.json').then(r => r.json()).then(j => console.log(JSON.stringify(j)))",
            self.url
        );
        let out = Command::new("node")
            .args(["--input-type=module", "-e", &script])
            .output()
            .context("running node")?;
        anyhow::ensure!(
            out.status.success(),
            "fetching stats: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Ok(serde_json::from_slice(&out.stdout)?)
    }
}

impl WebGatewayProcess {
    /// The `ADDR:PORT` it serves on.
    pub fn http_addr(&self) -> &str {
        self.url.trim_start_matches("http://").trim_end_matches('/')
    }
}

/// One browser tab on the page.
pub struct BrowserPage {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: Lines,
}

impl BrowserPage {
    /// Open `url` in headless chromium, `width` x `height` CSS pixels.
    pub fn open(url: &str, width: u32, height: u32) -> Result<Self> {
        let driver = web_root().join("tools/page_driver.mjs");
        let mut child = Command::new("node")
            .arg(&driver)
            .args([url, &width.to_string(), &height.to_string()])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .with_context(|| format!("starting node {}", driver.display()))?;
        let stdin = child.stdin.take();
        let lines = Lines::of(child.stdout.take().context("the driver's stdout")?);
        let mut page = Self {
            child,
            stdin,
            lines,
        };
        let ready = page.answer(Duration::from_secs(150))?;
        anyhow::ensure!(ready["ready"] == true, "the page did not open: {ready}");
        Ok(page)
    }

    fn answer(&mut self, timeout: Duration) -> Result<Value> {
        let line = self.lines.next(timeout).context("the page driver")?;
        let value: Value =
            serde_json::from_str(&line).with_context(|| format!("the driver said {line}"))?;
        if let Some(error) = value.get("error") {
            bail!("the page driver: {error}");
        }
        Ok(value)
    }

    fn ask(&mut self, command: &str, timeout: Duration) -> Result<Value> {
        let stdin = self.stdin.as_mut().context("the driver's stdin")?;
        writeln!(stdin, "{command}").context("writing to the driver")?;
        stdin.flush()?;
        self.answer(timeout)
    }

    /// `window.sinew` now, and the page's errors so far (`problems`).
    pub fn state(&mut self) -> Result<(Value, Vec<String>)> {
        let answer = self.ask("state", Duration::from_secs(30))?;
        let problems = answer["problems"]
            .as_array()
            .map(|p| p.iter().map(|s| s.to_string()).collect())
            .unwrap_or_default();
        Ok((answer["state"].clone(), problems))
    }

    /// Poll `window.sinew` until `condition` holds; returns it then, or the last state in the error.
    pub fn wait_for(
        &mut self,
        timeout: Duration,
        what: &str,
        condition: impl Fn(&Value) -> bool,
    ) -> Result<Value> {
        let started = std::time::Instant::now();
        loop {
            let (state, _) = self.state()?;
            if condition(&state) {
                return Ok(state);
            }
            if started.elapsed() > timeout {
                bail!("the page never showed {what} within {timeout:?}; it holds {state}");
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// Press the page's pause button (or release it): the picture holds still while the feed goes on, so a
    /// state read and a screenshot show the same frame.
    pub fn pause(&mut self, paused: bool) -> Result<()> {
        self.ask(
            if paused { "pause" } else { "resume" },
            Duration::from_secs(30),
        )?;
        Ok(())
    }

    /// From the page's origin, open a socket of its own to the feed and send `count` messages (text and
    /// binary) into it; returns how many were sent.
    pub fn write_to_feed(&mut self, count: u32) -> Result<u64> {
        let answer = self.ask(&format!("write {count}"), Duration::from_secs(30))?;
        answer["write"]
            .as_u64()
            .context("the driver's answer to write")
    }

    /// A PNG screenshot of the page.
    pub fn screenshot(&mut self, path: &Path) -> Result<image::RgbImage> {
        self.ask(&format!("shot {}", path.display()), Duration::from_secs(90))?;
        Ok(image::open(path)
            .with_context(|| format!("reading {}", path.display()))?
            .to_rgb8())
    }
}

impl Drop for BrowserPage {
    fn drop(&mut self) {
        if let Some(mut stdin) = self.stdin.take() {
            let _ = writeln!(stdin, "quit");
        }
        for _ in 0..50 {
            if matches!(self.child.try_wait(), Ok(Some(_))) {
                return;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Tissue pink as the page draws it (lit, textured, burns aside): red well above green and blue, which are
/// close to each other.
pub fn is_tissue(p: &image::Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    r > 110 && r - g > 45 && r - b > 35 && (g - b).abs() < 45 && g * 10 > r * 3
}

/// A tool as the page draws it: steel (low saturation, lighter than the background) or contact red (red far
/// above both green and blue).
pub fn is_tool(p: &image::Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    let (max, min) = (r.max(g).max(b), r.min(g).min(b));
    let steel = max - min < 40 && max > 55;
    let contact = r > 110 && g * 10 < r * 4 && b * 10 < r * 4;
    steel || contact
}

/// Pixels for which `test` holds within `radius` pixels of (`x`, `y`).
pub fn count_near(
    image: &image::RgbImage,
    x: f64,
    y: f64,
    radius: i64,
    test: impl Fn(&image::Rgb<u8>) -> bool,
) -> usize {
    let (cx, cy) = (x.round() as i64, y.round() as i64);
    let mut n = 0;
    for py in cy - radius..=cy + radius {
        for px in cx - radius..=cx + radius {
            if px < 0 || py < 0 || px >= i64::from(image.width()) || py >= i64::from(image.height())
            {
                continue;
            }
            if test(image.get_pixel(px as u32, py as u32)) {
                n += 1;
            }
        }
    }
    n
}
