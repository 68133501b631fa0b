// Drives the instructor's page in a real browser (Debian's chromium, headless) for the browser test
// (tests/tests/web_browser.rs), one command per line on stdin, one JSON line per answer on stdout:
//   state          -> window.sinew (what the page has replicated)
//   shot <file>    -> a PNG screenshot of the page, {"shot": file}
//   pause, resume  -> the page's pause button: the picture holds still (the feed keeps arriving)
//   write <n>      -> from the page's origin, a socket of its own sends n messages to the feed, {"write": n}
//   quit           -> closes the browser
// Usage: node page_driver.mjs <url> [width height]
import { chromium } from 'playwright-core';
import { createInterface } from 'node:readline';

const [url, width = '1280', height = '800'] = process.argv.slice(2);
if (!url) {
  console.error('usage: node page_driver.mjs <url> [width height]');
  process.exit(2);
}
const executablePath = process.env.SINEW_CHROMIUM ?? '/usr/bin/chromium';
const browser = await chromium.launch({
  executablePath,
  // A closed network: no background fetches; WebGL on the CPU (SwiftShader) with no GPU.
  args: ['--no-sandbox', '--disable-gpu-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--disable-quic', '--no-first-run', '--disable-background-networking', '--disable-component-update',
    '--disable-sync', '--ignore-gpu-blocklist'],
});
const page = await browser.newPage({ viewport: { width: Number(width), height: Number(height) } });
const problems = [];
page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
page.on('console', (m) => { if (m.type() === 'error') problems.push(`console: ${m.text()}`); });
// The page's scripts are modules (three.js is 1.3 MB): on a loaded 2-core machine with software WebGL they can
// take a while; the page reports itself through window.sinew, so the DOM is enough to start.
await page.goto(url, { waitUntil: 'domcontentloaded', timeout: 120_000 });
const say = (value) => process.stdout.write(`${JSON.stringify(value)}\n`);
say({ ready: true });
for await (const line of createInterface({ input: process.stdin })) {
  const [command, ...rest] = line.trim().split(' ');
  try {
    if (command === 'state') {
      say({ state: await page.evaluate(() => window.sinew ?? null), problems });
    } else if (command === 'pause' || command === 'resume') {
      // Hold the picture still (the page's own pause button), then render it once more, so a state read and
      // a screenshot show the same frame.
      await page.evaluate((paused) => window.sinewPause(paused), command === 'pause');
      await page.evaluate(() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done))));
      say({ [command]: true });
    } else if (command === 'write') {
      // Try to write to the scene through the feed: a socket of its own sends text and binary messages
      // (the page itself never sends). The gateway reads none of them.
      const sent = await page.evaluate((count) => new Promise((done) => {
        const socket = new WebSocket(`${location.origin.replace('http', 'ws')}/feed`);
        socket.onopen = () => {
          for (let i = 0; i < count; i++) socket.send(i % 2 ? new Uint8Array([3, 0, 0, 0, 255, 255]) : '{"pose":[0,0,-50]}');
          setTimeout(() => { socket.close(); done(count); }, 500);
        };
        socket.onerror = () => done(0);
      }), Number(rest[0] ?? '10'));
      say({ write: sent });
    } else if (command === 'shot') {
      await page.screenshot({ path: rest.join(' ') });
      say({ shot: rest.join(' ') });
    } else if (command === 'quit') {
      break;
    } else {
      say({ error: `unknown command ${command}` });
    }
  } catch (e) {
    say({ error: String(e) });
  }
}
await browser.close();
