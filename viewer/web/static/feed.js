// Reads sinew-web's feed (viewer/src/web_feed.rs documents the messages): every message is binary, with a
// 4-byte header (kind, flags, object) and a body. This file only decodes; app.js decides what to draw.

export const KIND_SCENE = 1;
export const KIND_MESH = 2;
export const KIND_POSITIONS = 3;
export const KIND_STATE = 4;
export const KIND_POSITIONS_DELTA = 5;
const FLAG_BURN = 1;
const text = new TextDecoder();

/** Decode one message, or return null for one this page cannot read (it is skipped and counted). */
export function decode(buffer) {
  if (!(buffer instanceof ArrayBuffer) || buffer.byteLength < 4) return null;
  const view = new DataView(buffer);
  const kind = view.getUint8(0);
  const flags = view.getUint8(1);
  const object = view.getUint16(2, true);
  try {
    switch (kind) {
      case KIND_SCENE:
      case KIND_STATE:
        return { kind, body: JSON.parse(text.decode(new Uint8Array(buffer, 4))) };
      case KIND_MESH: {
        const topologyEpoch = view.getUint32(4, true);
        const vertexCount = view.getUint32(8, true);
        const triangleCount = view.getUint32(12, true);
        if (buffer.byteLength !== 16 + triangleCount * 12) return null;
        return { kind, object, topologyEpoch, vertexCount, indices: new Uint32Array(buffer, 16, triangleCount * 3) };
      }
      case KIND_POSITIONS: {
        const vertexCount = view.getUint32(4, true);
        const min = [0, 1, 2].map((a) => view.getFloat32(8 + 4 * a, true));
        const quantum = [0, 1, 2].map((a) => view.getFloat32(20 + 4 * a, true));
        const burnt = (flags & FLAG_BURN) !== 0;
        if (buffer.byteLength !== 32 + vertexCount * (burnt ? 7 : 6)) return null;
        const q = new Uint16Array(buffer, 32, vertexCount * 3);
        const positions = new Float32Array(vertexCount * 3);
        for (let i = 0; i < vertexCount; i++) {
          for (let a = 0; a < 3; a++) positions[3 * i + a] = min[a] + q[3 * i + a] * quantum[a];
        }
        const burn = burnt ? new Uint8Array(buffer, 32 + vertexCount * 6, vertexCount) : null;
        return { kind, object, vertexCount, positions, burn };
      }
      case KIND_POSITIONS_DELTA: {
        const vertexCount = view.getUint32(4, true);
        const changed = view.getUint32(8, true);
        const min = [0, 1, 2].map((a) => view.getFloat32(12 + 4 * a, true));
        const quantum = [0, 1, 2].map((a) => view.getFloat32(24 + 4 * a, true));
        const burnt = (flags & FLAG_BURN) !== 0;
        if (buffer.byteLength !== 36 + changed * (burnt ? 11 : 10)) return null;
        const indices = new Uint32Array(buffer, 36, changed);
        const q = new Uint16Array(buffer, 36 + 4 * changed, changed * 3);
        const positions = new Float32Array(changed * 3);
        for (let k = 0; k < changed; k++) {
          for (let a = 0; a < 3; a++) positions[3 * k + a] = min[a] + q[3 * k + a] * quantum[a];
        }
        const burn = burnt ? new Uint8Array(buffer, 36 + 10 * changed, changed) : null;
        return { kind, object, vertexCount, indices, positions, burn };
      }
      default:
        return null;
    }
  } catch {
    return null;
  }
}
