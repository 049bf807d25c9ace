// node morph.mjs in.glb out.glb: drape's node-per-frame glb -> the same run as morph targets.
import fs from 'fs';
const b = fs.readFileSync(process.argv[2]);
const jl = b.readUInt32LE(12);
const doc = JSON.parse(b.subarray(20, 20 + jl).toString());
const bin = b.subarray(20 + jl + 8);
const acc = (a) => { const A = doc.accessors[a], V = doc.bufferViews[A.bufferView];
  const n = A.count * (A.type === 'VEC3' ? 3 : 1);
  return A.componentType === 5126 ? new Float32Array(bin.buffer.slice(bin.byteOffset + V.byteOffset, bin.byteOffset + V.byteOffset + n * 4))
                                 : new Uint32Array(bin.buffer.slice(bin.byteOffset + V.byteOffset, bin.byteOffset + V.byteOffset + n * 4)); };
const frames = doc.nodes.filter((n) => /^frame_/.test(n.name));
const F = frames.length;
const out = { asset: doc.asset, scene: 0, accessors: [], bufferViews: [], buffers: [], meshes: [], nodes: [], materials: doc.materials, cameras: doc.cameras, animations: [] };
const chunks = []; let size = 0;
function add(arr, type, bounds) {
  const bytes = Buffer.from(arr.buffer, arr.byteOffset, arr.byteLength);
  out.bufferViews.push({ buffer: 0, byteOffset: size, byteLength: bytes.length }); chunks.push(bytes); size += bytes.length;
  const a = { bufferView: out.bufferViews.length - 1, componentType: arr instanceof Float32Array ? 5126 : 5125, count: arr.length / (type === 'VEC3' ? 3 : 1), type };
  if (bounds) { const w = type === 'VEC3' ? 3 : 1; a.min = []; a.max = [];
    for (let c = 0; c < w; ++c) { let lo = Infinity, hi = -Infinity; for (let k = c; k < arr.length; k += w) { lo = Math.min(lo, arr[k]); hi = Math.max(hi, arr[k]); } a.min.push(lo); a.max.push(hi); } }
  out.accessors.push(a); return out.accessors.length - 1;
}
const m0 = doc.meshes[frames[0].mesh];
const prims = m0.primitives.map((p, s) => {
  const p0 = acc(p.attributes.POSITION), n0 = acc(p.attributes.NORMAL);
  const targets = [];
  for (let k = 1; k < F; ++k) {
    const q = doc.meshes[frames[k].mesh].primitives[s];
    const pk = acc(q.attributes.POSITION), nk = acc(q.attributes.NORMAL);
    const dp = pk.map((v, i) => v - p0[i]), dn = nk.map((v, i) => v - n0[i]);
    targets.push({ POSITION: add(dp, 'VEC3', true), NORMAL: add(dn, 'VEC3', false) });
  }
  return { attributes: { POSITION: add(p0, 'VEC3', true), NORMAL: add(n0, 'VEC3', false) }, indices: add(acc(p.indices), 'SCALAR', false), material: 0, targets };
});
out.meshes.push({ name: 'sheets', primitives: prims, weights: new Array(F - 1).fill(0) });
const times = doc.scenes[0].extras.drape.times;
const keys = new Float32Array(times.map((t) => t - times[0]));
const w = new Float32Array(F * (F - 1)); for (let k = 1; k < F; ++k) w[k * (F - 1) + (k - 1)] = 1;
out.animations.push({ name: 'run', samplers: [{ input: add(keys, 'SCALAR', true), output: add(w, 'SCALAR', false), interpolation: 'STEP' }], channels: [{ sampler: 0, target: { node: 1, path: 'weights' } }] });
out.nodes.push({ name: 'drape (z up)', rotation: doc.nodes[0].rotation, children: [1] });
out.nodes.push({ name: 'sheets', mesh: 0 });
out.scenes = [{ nodes: [0], extras: doc.scenes[0].extras }];
out.buffers.push({ byteLength: size });
let json = Buffer.from(JSON.stringify(out)); const pad = (4 - json.length % 4) % 4; json = Buffer.concat([json, Buffer.alloc(pad, 32)]);
const body = Buffer.concat(chunks); const bpad = (4 - body.length % 4) % 4; const binc = Buffer.concat([body, Buffer.alloc(bpad)]);
const head = Buffer.alloc(12); head.writeUInt32LE(0x46546C67, 0); head.writeUInt32LE(2, 4); head.writeUInt32LE(12 + 8 + json.length + 8 + binc.length, 8);
const jh = Buffer.alloc(8); jh.writeUInt32LE(json.length, 0); jh.writeUInt32LE(0x4E4F534A, 4);
const bh = Buffer.alloc(8); bh.writeUInt32LE(binc.length, 0); bh.writeUInt32LE(0x004E4942, 4);
fs.writeFileSync(process.argv[3], Buffer.concat([head, jh, json, bh, binc]));
console.log(`${process.argv[2]}: ${b.length} bytes as nodes, ${12 + 16 + json.length + binc.length} as morph targets (${F} frames)`);
