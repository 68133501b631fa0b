// The instructor's page: opens sinew-web's feed, keeps the 3D view and the panel in step with it, and
// reconnects (catching up in one go) if the gateway goes away. Read-only: it never sends on the socket.
//
// `window.sinew` holds what the page has replicated (scene, objects with their vertex counts and topology
// epochs, messages and bytes received): for the browser test and for anyone debugging from the console.
import { decode, KIND_SCENE, KIND_MESH, KIND_POSITIONS, KIND_POSITIONS_DELTA, KIND_STATE } from './feed.js';
import { SceneView } from './scene.js';
import { Panel } from './panel.js';

const view = new SceneView(document.getElementById('view'));
const panel = new Panel(document.getElementById('overlay'), document.getElementById('plot'));
const status = document.getElementById('status');
const feedStats = document.getElementById('feed-stats');

const sinew = {
  connected: false, connections: 0, scene: null, layout: null, objects: [], tools: [],
  paused: false, messages: 0, bytes: 0, undecodable: 0, unapplied: 0, states: 0, lastStateFrame: 0, parts: 0, arrows: 0, arrowsDrawn: [], rendered: 0,
};
window.sinew = sinew;

function objectsSummary() {
  sinew.objects = [...view.objects.entries()].map(([index, o]) => ({
    index, name: sinew.sceneObjects?.find((s) => s.index === index)?.name ?? '',
    vertexCount: o.vertexCount, topologyEpoch: o.topologyEpoch,
    triangleCount: o.geometry.index ? o.geometry.index.count / 3 : 0, positionsReceived: o.positionsReceived,
    deltasReceived: o.deltasReceived, drawnMinZ: o.drawnMinZ, drawnMeanZ: o.drawnMeanZ,
  }));
}

function onMessage(buffer) {
  sinew.messages += 1;
  sinew.bytes += buffer.byteLength;
  const m = decode(buffer);
  if (!m) { sinew.undecodable += 1; return; }
  switch (m.kind) {
    case KIND_SCENE:
      view.resetObjects();
      sinew.scene = m.body.scene;
      sinew.layout = m.body.layout;
      sinew.sceneObjects = m.body.objects;
      sinew.tools = m.body.tools;
      document.title = `Sinew: watching ${m.body.scene}`;
      break;
    case KIND_MESH: view.setMesh(m); break;
    // Positions go into the page's copy of each object at once (a change applies to the one before it);
    // the GPU takes them once per drawn frame. The state is a latest-value mailbox.
    case KIND_POSITIONS: if (!view.takePositions(m)) sinew.unapplied += 1; break;
    case KIND_POSITIONS_DELTA: if (!view.takeDelta(m)) sinew.unapplied += 1; break;
    case KIND_STATE: pendingState = m.body; break;
  }
  objectsSummary();
}

let pendingState = null;

/** Hold the picture (the newest positions and state wait in the mailboxes) or let it go on. */
function setPaused(paused) {
  sinew.paused = paused;
  const button = document.getElementById('pause');
  button.classList.toggle('on', paused);
  button.textContent = paused ? 'resume' : 'pause';
}
window.sinewPause = setPaused;
document.getElementById('pause').addEventListener('click', () => setPaused(!sinew.paused));

/** Apply what arrived since the last frame (unless paused); returns whether anything did. */
function applyPending() {
  if (sinew.paused) return false;
  let changed = view.flush();
  if (pendingState) {
    const state = pendingState;
    pendingState = null;
    view.setState(state);
    panel.setState(state);
    sinew.states += 1;
    sinew.lastStateFrame = state.frame;
    sinew.parts = state.tools.reduce((n, t) => n + t.parts.length, 0);
    sinew.arrows = state.arrows.length;
    sinew.arrowsDrawn = view.arrowsDrawn;
    changed = true;
  }
  if (changed) objectsSummary();
  return changed;
}

function connect() {
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/feed`;
  const socket = new WebSocket(url);
  socket.binaryType = 'arraybuffer';
  socket.onopen = () => {
    sinew.connected = true; sinew.connections += 1;
    status.textContent = 'live'; status.className = 'status live';
  };
  socket.onmessage = (event) => onMessage(event.data);
  socket.onclose = () => {
    sinew.connected = false;
    status.textContent = 'reconnecting'; status.className = 'status';
    setTimeout(connect, 1000);
  };
}

let bytesAtLastSecond = 0, statesAtLastSecond = 0;
setInterval(() => {
  const rate = sinew.bytes - bytesAtLastSecond, states = sinew.states - statesAtLastSecond;
  bytesAtLastSecond = sinew.bytes; statesAtLastSecond = sinew.states;
  sinew.bytesPerS = rate; sinew.statesPerS = states;
  feedStats.textContent = `${sinew.scene ?? '-'}: ${states} updates/s, ${(rate / 1024).toFixed(0)} KiB/s, ` +
    `${sinew.objects.reduce((n, o) => n + o.vertexCount, 0)} vertices`;
}, 1000);

for (const [id, preset] of [['camera-orbit', 'orbit'], ['camera-scope', 'scope']]) {
  document.getElementById(id).addEventListener('click', () => {
    view.setPreset(preset);
    for (const b of document.querySelectorAll('header button')) b.classList.toggle('on', b.id === id);
  });
}

let cameraMoved = true;
view.controls.addEventListener('change', () => { cameraMoved = true; });
window.addEventListener('resize', () => { cameraMoved = true; });
function animate() {
  // Draw only when the scene or the camera changed: an idle page costs nothing.
  const changed = applyPending();
  view.controls.update();
  if (changed || cameraMoved) {
    cameraMoved = false;
    view.render();
    sinew.rendered += 1;
    sinew.toolsOnScreen = view.toolsOnScreen();
  }
  requestAnimationFrame(animate);
}
connect();
animate();
