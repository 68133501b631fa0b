// The 3D view: tissue meshes kept in step with the feed, tools drawn as the parts the gateway sends (balls,
// capsules, meshes), force arrows, target rings and suture threads; lights, shadows and two camera presets.
// World frame as the server's: millimetres, z up.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { RoomEnvironment } from 'three/addons/environments/RoomEnvironment.js';

const TISSUE_RGB = [0.92, 0.46, 0.50];
// Burn colours by level, as the native viewer's: seared, cooked, charred.
const BURN = [[1, [0.93, 0.80, 0.30]], [96, [0.45, 0.27, 0.12]], [192, [0.08, 0.06, 0.05]]];
const THREAD_RGB = [0.42, 0.20, 0.78];

function srgb(rgb) { return new THREE.Color().setRGB(rgb[0], rgb[1], rgb[2], THREE.SRGBColorSpace); }

/** A mottled, faintly veined texture for tissue, made here (no image file): value noise in a few octaves. */
function tissueTexture() {
  const size = 256;
  const data = new Uint8Array(size * size * 4);
  const lattice = (x, y, seed) => {
    const s = Math.sin(x * 127.1 + y * 311.7 + seed * 74.7) * 43758.5453;
    return s - Math.floor(s);
  };
  const noise = (x, y, period, seed) => {
    const xi = Math.floor(x), yi = Math.floor(y), xf = x - xi, yf = y - yi;
    const w = (i) => ((i % period) + period) % period;
    const sx = xf * xf * (3 - 2 * xf), sy = yf * yf * (3 - 2 * yf);
    const a = lattice(w(xi), w(yi), seed), b = lattice(w(xi + 1), w(yi), seed);
    const c = lattice(w(xi), w(yi + 1), seed), d = lattice(w(xi + 1), w(yi + 1), seed);
    return a + (b - a) * sx + (c - a) * sy + (a - b - c + d) * sx * sy;
  };
  for (let y = 0; y < size; y++) {
    for (let x = 0; x < size; x++) {
      let n = 0, amp = 0.5, f = 8;
      for (let o = 0; o < 4; o++) { n += amp * noise((x * f) / size, (y * f) / size, f, o); amp *= 0.5; f *= 2; }
      const vein = Math.pow(1 - Math.abs(2 * noise((x * 6) / size, (y * 6) / size, 6, 9) - 1), 24);
      const k = 4 * (y * size + x);
      const shade = 0.84 + 0.22 * n - 0.12 * vein;
      data[k] = Math.min(255, 255 * shade);
      data[k + 1] = Math.min(255, 255 * (shade - 0.06 * vein));
      data[k + 2] = Math.min(255, 255 * (shade + 0.05 * vein));
      data[k + 3] = 255;
    }
  }
  const texture = new THREE.DataTexture(data, size, size, THREE.RGBAFormat);
  texture.wrapS = texture.wrapT = THREE.RepeatWrapping;
  texture.colorSpace = THREE.SRGBColorSpace;
  texture.needsUpdate = true;
  return texture;
}

export class SceneView {
  constructor(container) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.renderer.shadowMap.enabled = true;
    this.renderer.shadowMap.type = THREE.PCFSoftShadowMap;
    this.renderer.toneMapping = THREE.ACESFilmicToneMapping;
    this.renderer.toneMappingExposure = 1.1;
    container.appendChild(this.renderer.domElement);

    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x1c1f26);
    // Soft reflections for steel and the wet sheen of tissue, from a room lit from above (made once, here).
    const pmrem = new THREE.PMREMGenerator(this.renderer);
    this.scene.environment = pmrem.fromScene(new RoomEnvironment(), 0.04).texture;
    this.scene.environmentIntensity = 0.35;
    pmrem.dispose();
    this.camera = new THREE.PerspectiveCamera(40, 1, 1, 5000);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(0, -140, 110);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.enableDamping = true;
    this.preset = 'orbit';

    this.scene.add(new THREE.HemisphereLight(0xfff4f0, 0x30262a, 0.9));
    this.key = new THREE.DirectionalLight(0xffffff, 2.2);
    this.key.position.set(-60, -50, 160);
    this.key.castShadow = true;
    this.key.shadow.mapSize.set(1024, 1024);
    this.key.shadow.bias = -0.0005;
    this.key.shadow.normalBias = 0.3;
    this.scene.add(this.key, this.key.target);
    const fill = new THREE.DirectionalLight(0xdde6ff, 0.5);
    fill.position.set(80, 40, 60);
    this.scene.add(fill);

    this.texture = tissueTexture();
    this.tissue = new THREE.MeshPhysicalMaterial({
      color: 0xffffff, vertexColors: true, map: this.texture, roughness: 0.55, metalness: 0,
      clearcoat: 0.7, clearcoatRoughness: 0.18, sheen: 0.3, sheenColor: new THREE.Color(0xffc0c8),
      side: THREE.DoubleSide,
    });
    // object index -> { mesh, geometry, vertexCount, topologyEpoch, positions and burn (the copy the feed
    // updates), dirty (not yet on the GPU) }
    this.objects = new Map();
    this.tissueColour = srgb(TISSUE_RGB);
    this.burnColours = BURN.map(([level, rgb]) => [level, srgb(rgb)]);
    this.tools = new THREE.Group();
    this.overlay = new THREE.Group();
    this.scene.add(this.tools, this.overlay);
    this.capsules = new Map(); // "r:len" -> geometry
    this.steel = new Map(); // rgb key -> material
    this.framed = false;
    this.resize();
    window.addEventListener('resize', () => this.resize());
  }

  resize() {
    const w = this.container.clientWidth || 640, h = this.container.clientHeight || 480;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  /** The layout changed (a new scene, a cut): drop every mesh; MESH messages follow. */
  resetObjects() {
    for (const o of this.objects.values()) { this.scene.remove(o.mesh); o.geometry.dispose(); }
    this.objects.clear();
  }

  setMesh(message) {
    const old = this.objects.get(message.object);
    if (old) { this.scene.remove(old.mesh); old.geometry.dispose(); }
    const geometry = new THREE.BufferGeometry();
    const n = message.vertexCount;
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(n * 3), 3));
    geometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(n * 3).fill(1), 3));
    geometry.setAttribute('uv', new THREE.BufferAttribute(new Float32Array(n * 2), 2));
    geometry.setIndex(new THREE.BufferAttribute(new Uint32Array(message.indices), 1));
    const mesh = new THREE.Mesh(geometry, this.tissue);
    mesh.castShadow = true;
    mesh.receiveShadow = true;
    mesh.visible = false; // until its positions arrive
    this.scene.add(mesh);
    this.objects.set(message.object, {
      mesh, geometry, vertexCount: n, topologyEpoch: message.topologyEpoch, uvDone: false, positionsReceived: 0,
      deltasReceived: 0, positions: new Float32Array(n * 3), burn: new Uint8Array(n), hasPositions: false,
      dirty: false,
    });
  }

  /** Every position of an object (a POSITIONS message), into its copy here; drawn at the next flush. */
  takePositions(message) {
    const o = this.objects.get(message.object);
    if (!o || o.vertexCount !== message.vertexCount) return false;
    o.positions.set(message.positions);
    if (message.burn) o.burn.set(message.burn); else o.burn.fill(0);
    o.hasPositions = true;
    o.dirty = true;
    o.positionsReceived += 1;
    return true;
  }

  /** The vertices that moved (a POSITIONS_DELTA message), into the copy here; false if it does not fit. */
  takeDelta(message) {
    const o = this.objects.get(message.object);
    if (!o || !o.hasPositions || o.vertexCount !== message.vertexCount) return false;
    for (let k = 0; k < message.indices.length; k++) {
      const i = message.indices[k];
      if (i >= o.vertexCount) return false;
      o.positions[3 * i] = message.positions[3 * k];
      o.positions[3 * i + 1] = message.positions[3 * k + 1];
      o.positions[3 * i + 2] = message.positions[3 * k + 2];
      if (message.burn) o.burn[i] = message.burn[k];
    }
    o.dirty = true;
    o.positionsReceived += 1;
    o.deltasReceived += 1;
    return true;
  }

  /** Write every changed object to the GPU (positions, burn colours, normals); returns whether any changed. */
  flush() {
    let any = false;
    for (const o of this.objects.values()) {
      if (!o.dirty) continue;
      o.dirty = false;
      any = true;
      const position = o.geometry.getAttribute('position');
      position.array.set(o.positions);
      position.needsUpdate = true;
      if (!o.uvDone) {
        // Texture coordinates from where the vertices first are (planar, 1 repeat per 40 mm): the pattern
        // then moves with the tissue as it deforms.
        const uv = o.geometry.getAttribute('uv');
        for (let i = 0; i < o.vertexCount; i++) {
          uv.array[2 * i] = o.positions[3 * i] / 40;
          uv.array[2 * i + 1] = (o.positions[3 * i + 1] + 0.35 * o.positions[3 * i + 2]) / 40;
        }
        uv.needsUpdate = true;
        o.uvDone = true;
      }
      const colour = o.geometry.getAttribute('color');
      for (let i = 0; i < o.vertexCount; i++) {
        let c = this.tissueColour;
        for (const [from, burnt] of this.burnColours) if (o.burn[i] >= from) c = burnt;
        colour.array[3 * i] = c.r; colour.array[3 * i + 1] = c.g; colour.array[3 * i + 2] = c.b;
      }
      colour.needsUpdate = true;
      o.geometry.computeVertexNormals();
      o.geometry.computeBoundingSphere();
      o.mesh.visible = true;
      // What is drawn, summed up: for the browser test, to compare with a viewer's replica.
      let minZ = Infinity, sumZ = 0;
      for (let i = 0; i < o.vertexCount; i++) { const z = o.positions[3 * i + 2]; minZ = Math.min(minZ, z); sumZ += z; }
      o.drawnMinZ = minZ;
      o.drawnMeanZ = sumZ / Math.max(1, o.vertexCount);
    }
    if (any && !this.framed) this.frame();
    return any;
  }

  bounds() {
    const box = new THREE.Box3();
    for (const o of this.objects.values()) if (o.mesh.visible) box.expandByObject(o.mesh);
    return box;
  }

  /** Point the camera at the tissue (on the first positions, and when a preset is chosen). */
  frame() {
    const box = this.bounds();
    if (box.isEmpty()) return;
    this.framed = true;
    const centre = box.getCenter(new THREE.Vector3());
    const radius = Math.max(20, box.getSize(new THREE.Vector3()).length() / 2);
    this.controls.target.copy(centre);
    this.key.target.position.copy(centre);
    const s = this.key.shadow.camera;
    s.left = s.bottom = -1.6 * radius; s.right = s.top = 1.6 * radius; s.near = 1; s.far = 600;
    s.updateProjectionMatrix();
    if (this.preset === 'scope') {
      // A 0-degree laparoscope through a port to one side: close, wide, looking down at about 40 degrees.
      this.camera.fov = 70;
      this.camera.position.set(centre.x - 0.25 * radius, centre.y - 0.75 * radius, centre.z + 0.65 * radius);
    } else {
      this.camera.fov = 40;
      this.camera.position.set(centre.x, centre.y - 2.0 * radius, centre.z + 1.7 * radius);
    }
    this.camera.updateProjectionMatrix();
    this.controls.update();
  }

  setPreset(preset) { this.preset = preset; this.frame(); this.controls.dispatchEvent({ type: 'change' }); }

  material(rgb, metal) {
    const key = `${rgb.join(',')}:${metal}`;
    let m = this.steel.get(key);
    if (!m) {
      m = new THREE.MeshStandardMaterial({ color: srgb(rgb), metalness: metal ? 0.6 : 0.1, roughness: metal ? 0.3 : 0.5 });
      this.steel.set(key, m);
    }
    return m;
  }

  capsule(radius, length) {
    const key = `${radius.toFixed(3)}:${length.toFixed(3)}`;
    let g = this.capsules.get(key);
    if (!g) { g = new THREE.CapsuleGeometry(radius, length, 6, 16); this.capsules.set(key, g); }
    return g;
  }

  sphere(radius) {
    const key = `s${radius.toFixed(3)}`;
    let g = this.capsules.get(key);
    if (!g) { g = new THREE.SphereGeometry(radius, 24, 16); this.capsules.set(key, g); }
    return g;
  }

  /** Tools, arrows, rings and threads from one STATE message (rebuilt: a few dozen objects). */
  setState(state) {
    for (const child of [...this.tools.children]) {
      this.tools.remove(child);
      if (child.userData.own) child.geometry.dispose();
    }
    for (const child of [...this.overlay.children]) {
      this.overlay.remove(child);
      child.traverse((c) => { if (c.geometry) c.geometry.dispose(); });
    }
    const up = new THREE.Vector3(0, 1, 0);
    // Each tool's body centre (its first part), for toolsOnScreen.
    this.toolCentres = state.tools.filter((t) => t.parts.length).map((t) => {
      const p = t.parts[0];
      const c = p.kind === 'sphere' ? p.c : p.kind === 'capsule' ? p.a.map((v, i) => 0.5 * (v + p.b[i])) : p.positions[0];
      return { tool: t.tool, deviceId: t.deviceId, centre: c };
    });
    for (const tool of state.tools) {
      for (const part of tool.parts) {
        let mesh;
        if (part.kind === 'sphere') {
          mesh = new THREE.Mesh(this.sphere(part.r), this.material(part.rgb, true));
          mesh.position.fromArray(part.c);
        } else if (part.kind === 'capsule') {
          const a = new THREE.Vector3().fromArray(part.a), b = new THREE.Vector3().fromArray(part.b);
          const along = b.clone().sub(a);
          const length = along.length();
          mesh = new THREE.Mesh(this.capsule(part.r, length), this.material(part.rgb, true));
          mesh.position.copy(a).add(b).multiplyScalar(0.5);
          mesh.quaternion.setFromUnitVectors(up, along.normalize());
        } else if (part.kind === 'mesh') {
          const g = new THREE.BufferGeometry();
          g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(part.positions.flat()), 3));
          g.setIndex(part.triangles.flat());
          g.computeVertexNormals();
          mesh = new THREE.Mesh(g, this.material(part.rgb, true));
          mesh.userData.own = true;
        } else continue;
        mesh.castShadow = true;
        this.tools.add(mesh);
      }
    }
    // The arrows drawn (one shorter than 0.5 mm is not): their length, mm, and colour, for the page's state.
    this.arrowsDrawn = [];
    for (const arrow of state.arrows) {
      const from = new THREE.Vector3().fromArray(arrow.from), to = new THREE.Vector3().fromArray(arrow.to);
      const along = to.clone().sub(from);
      const length = along.length();
      if (!(length > 0.5)) continue;
      this.arrowsDrawn.push({ lengthMm: length, rgb: arrow.rgb });
      const helper = new THREE.ArrowHelper(along.normalize(), from, length, srgb(arrow.rgb), Math.min(6, 0.3 * length), Math.min(3.5, 0.18 * length));
      helper.line.material.depthTest = false;
      helper.cone.material.depthTest = false;
      helper.renderOrder = 10;
      this.overlay.add(helper);
    }
    for (const ring of state.targets) {
      const points = [];
      for (let k = 0; k <= 48; k++) {
        const t = (2 * Math.PI * k) / 48;
        points.push(new THREE.Vector3(ring.centre[0] + ring.radiusMm * Math.cos(t), ring.centre[1] + ring.radiusMm * Math.sin(t), ring.centre[2] + 0.3));
      }
      this.overlay.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints(points), new THREE.LineBasicMaterial({ color: srgb(ring.rgb) })));
    }
    for (const thread of state.threads) {
      if (thread.length < 2) continue;
      const path = new THREE.CurvePath();
      for (let k = 0; k + 1 < thread.length; k++) {
        path.add(new THREE.LineCurve3(new THREE.Vector3().fromArray(thread[k]), new THREE.Vector3().fromArray(thread[k + 1])));
      }
      const tube = new THREE.Mesh(new THREE.TubeGeometry(path, Math.max(8, thread.length * 2), 0.35, 6, false), this.material(THREAD_RGB, false));
      tube.castShadow = true;
      this.overlay.add(tube);
    }
  }

  /** Where each tool's body centre is on the page, CSS pixels from the page's top-left corner. */
  toolsOnScreen() {
    const rect = this.renderer.domElement.getBoundingClientRect();
    return (this.toolCentres ?? []).map(({ tool, deviceId, centre }) => {
      const v = new THREE.Vector3().fromArray(centre).project(this.camera);
      return { tool, deviceId, x: rect.left + ((v.x + 1) / 2) * rect.width, y: rect.top + ((1 - v.y) / 2) * rect.height, inFront: v.z < 1 };
    });
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }
}
