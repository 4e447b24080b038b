// Writes the small glTF inputs the viewer tests need into a folder (argv[2]):
//   beam.glb       one tapered cantilever (taper 0.1) with Sylva's wind attributes and table
//   beam_origin.glb, beam_scan.xyz  the beam at asset.extras.origin and its vertices as a Z-up scan there
//   fork.glb       a trunk and one horizontal child at half its height (children follow parents)
//   leaf_hl2.glb   a double-sided leaf quad with HL2 translucency maps (SYLVA_leaf_translucency)
//   leaf_dt.glb    the same quad with KHR_materials_diffuse_transmission only
//   lod.glb        three boxes as MSFT_lod levels with MSFT_screencoverage [0.5, 0.2, 0.05]
//   nomesh.glb     a valid file whose scene has no mesh
//   corrupt.glb    a truncated copy of beam.glb
//   missing_texture.gltf  a material whose image file does not exist
// and beam.json: the beam's analytic cantilever deflection (Habel 2009 eq. 4.7) at x = i/20.
import { writeFileSync } from 'node:fs';
import { deflateSync } from 'node:zlib';

const dir = process.argv[2];

function glb(json, bin) {
  const pad = (b, fill) => Buffer.concat([b, Buffer.alloc((4 - (b.length % 4)) % 4, fill)]);
  const j = pad(Buffer.from(JSON.stringify(json)), 0x20), bb = pad(bin, 0);
  const head = Buffer.alloc(12), jh = Buffer.alloc(8), bh = Buffer.alloc(8);
  head.write('glTF', 0); head.writeUInt32LE(2, 4); head.writeUInt32LE(12 + 8 + j.length + 8 + bb.length, 8);
  jh.writeUInt32LE(j.length, 0); jh.write('JSON', 4); bh.writeUInt32LE(bb.length, 0); bh.write('BIN\0', 4);
  return Buffer.concat([head, jh, j, bh, bb]);
}

// Accumulates typed arrays into one buffer with a bufferView and accessor each.
class Builder {
  constructor() { this.parts = []; this.len = 0; this.json = { asset: { version: '2.0', generator: 'sylva viewer test fixtures' }, buffers: [], bufferViews: [], accessors: [] }; }
  add(arr, type, componentType, target, minmax) {
    const b = Buffer.from(arr.buffer, arr.byteOffset, arr.byteLength);
    const view = { buffer: 0, byteOffset: this.len, byteLength: b.length };
    if (target) view.target = target;
    this.parts.push(b, Buffer.alloc((4 - (b.length % 4)) % 4));
    this.len += b.length + ((4 - (b.length % 4)) % 4);
    this.json.bufferViews.push(view);
    const n = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4 }[type];
    const acc = { bufferView: this.json.bufferViews.length - 1, componentType, count: arr.length / n, type };
    if (minmax) {
      acc.min = []; acc.max = [];
      for (let c = 0; c < n; c++) { let lo = Infinity, hi = -Infinity; for (let i = c; i < arr.length; i += n) { lo = Math.min(lo, arr[i]); hi = Math.max(hi, arr[i]); } acc.min.push(lo); acc.max.push(hi); }
    }
    this.json.accessors.push(acc);
    return this.json.accessors.length - 1;
  }
  image(png) {
    const b = png;
    this.parts.push(b, Buffer.alloc((4 - (b.length % 4)) % 4));
    this.json.bufferViews.push({ buffer: 0, byteOffset: this.len, byteLength: b.length });
    this.len += b.length + ((4 - (b.length % 4)) % 4);
    this.json.images = this.json.images || [];
    this.json.images.push({ bufferView: this.json.bufferViews.length - 1, mimeType: 'image/png' });
    return this.json.images.length - 1;
  }
  finish() { const bin = Buffer.concat(this.parts); this.json.buffers = [{ byteLength: bin.length }]; return glb(this.json, bin); }
}

// A PNG of one colour (RGBA8), w x h.
function solidPng(w, h, rgba) {
  const crcTable = Array.from({ length: 256 }, (_, n) => { let c = n; for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1; return c >>> 0; });
  const crc = (b) => { let c = 0xffffffff; for (const x of b) c = crcTable[(c ^ x) & 255] ^ (c >>> 8); return (c ^ 0xffffffff) >>> 0; };
  const chunk = (kind, data) => { const l = Buffer.alloc(4); l.writeUInt32BE(data.length); const kd = Buffer.concat([Buffer.from(kind), data]); const c = Buffer.alloc(4); c.writeUInt32BE(crc(kd)); return Buffer.concat([l, kd, c]); };
  const ihdr = Buffer.alloc(13); ihdr.writeUInt32BE(w, 0); ihdr.writeUInt32BE(h, 4); ihdr[8] = 8; ihdr[9] = 6;
  const raw = Buffer.alloc(h * (w * 4 + 1));
  for (let y = 0; y < h; y++) for (let x = 0; x < w; x++) raw.set(rgba, y * (w * 4 + 1) + 1 + x * 4);
  return Buffer.concat([Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a]), chunk('IHDR', ihdr), chunk('IDAT', deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]);
}

// Tapered Euler-Bernoulli cantilever under a uniform load, unit prefactor (Habel 2009 eq. 4.7).
function beamU(x, a) {
  const t = x * (a - 1);
  return (t * (6 + t * (2 * t * (3 + (a - 3) * a) + 3 * (4 + (a - 2) * a))) - 6 * (1 + t) ** 2 * Math.log(1 + t)) / (3 * Math.PI * (1 + t) ** 2 * (a - 1) ** 4);
}
// Least squares u ~ c2 x^2 + c4 x^4 on x = i/100 (as the exporter fits it, docs/wind.md).
function fit(a) {
  let s44 = 0, s46 = 0, s88 = 0, b2 = 0, b4 = 0;
  for (let i = 0; i <= 100; i++) { const x = i / 100, u = beamU(x, a); s44 += x ** 4; s46 += x ** 6; s88 += x ** 8; b2 += u * x ** 2; b4 += u * x ** 4; }
  const det = s44 * s88 - s46 * s46;
  return [(b2 * s88 - b4 * s46) / det, (s44 * b4 - s46 * b2) / det];
}

// --- beam.glb: a tube along +Y, length 2 m, radius 0.05 -> 0.005 (taper 0.1). ---
{
  const L = 2, r1 = 0.05, alpha = 0.1, rings = 41, sides = 8;
  const pos = [], nrm = [], ww = [], wb = [], wa = [], wl = [], idx = [];
  for (let i = 0; i < rings; i++) {
    const x = i / (rings - 1), r = r1 * (1 + (alpha - 1) * x);
    for (let k = 0; k < sides; k++) {
      const th = (2 * Math.PI * k) / sides;
      pos.push(r * Math.cos(th), L * x, r * Math.sin(th)); nrm.push(Math.cos(th), 0, Math.sin(th));
      ww.push(x, 0, 0, 0); wb.push(0); wa.push(0, 0, 0); wl.push(0, 0);
    }
  }
  for (let i = 0; i + 1 < rings; i++) for (let k = 0; k < sides; k++) {
    const a = i * sides + k, b = i * sides + ((k + 1) % sides), c = a + sides, d = b + sides;
    idx.push(a, c, b, b, c, d);
  }
  const B = new Builder();
  const attrs = {
    POSITION: B.add(new Float32Array(pos), 'VEC3', 5126, 34962, true), NORMAL: B.add(new Float32Array(nrm), 'VEC3', 5126, 34962),
    _WIND_W: B.add(new Float32Array(ww), 'VEC4', 5126, 34962), _WIND_BRANCH: B.add(new Float32Array(wb), 'SCALAR', 5126, 34962),
    _WIND_ANCHOR: B.add(new Float32Array(wa), 'VEC3', 5126, 34962), _WIND_LEVEL_STIFFNESS: B.add(new Float32Array(wl), 'VEC2', 5126, 34962),
  };
  const ind = B.add(new Uint16Array(idx), 'SCALAR', 5123, 34963);
  const [c2, c4] = fit(alpha);
  B.json.materials = [{ name: 'bark', pbrMetallicRoughness: { baseColorFactor: [0.4, 0.3, 0.2, 1], metallicFactor: 0, roughnessFactor: 0.9 } }];
  B.json.meshes = [{ name: 'beam', primitives: [{ attributes: attrs, indices: ind, material: 0 }] }];
  B.json.nodes = [{ name: 'beam', mesh: 0, extras: { sylva_wind: { version: 1, count: 1, parent: [-1], level: [0], anchor: [0, 0, 0], axis: [0, 1, 0], length: [L], c2: [c2], c4: [c4], frequency: [2.55 * L ** -0.59], stiffness: [0] } } }];
  B.json.scenes = [{ nodes: [0] }]; B.json.scene = 0;
  const file = B.finish();
  writeFileSync(`${dir}/beam.glb`, file);
  // The same beam placed in a survey frame, and a "scan" of its vertices there (Z up).
  const origin = [1000.5, 2000.25, 10];
  B.json.asset.extras = { origin };
  writeFileSync(`${dir}/beam_origin.glb`, B.finish());
  const lines = [];
  for (let i = 0; i < pos.length; i += 3) lines.push(`${(pos[i] + origin[0]).toFixed(4)} ${(-pos[i + 2] + origin[1]).toFixed(4)} ${(pos[i + 1] + origin[2]).toFixed(4)}`);
  writeFileSync(`${dir}/beam_scan.xyz`, lines.join('\n') + '\n');
  writeFileSync(`${dir}/corrupt.glb`, file.subarray(0, Math.floor(file.length * 0.6)));
  const u = []; for (let i = 0; i <= 20; i++) u.push(beamU(i / 20, alpha));
  writeFileSync(`${dir}/beam.json`, JSON.stringify({ length: L, alpha, c2, c4, x: u.map((_, i) => i / 20), u }));
}

// --- fork.glb: trunk (branch 0, 2 m up +Y) and a child (branch 1, 1 m along +Z from y = 1). ---
{
  const L = [2, 1], sides = 8, rings = 11;
  const pos = [], ww = [], wb = [], idx = [];
  const tube = (branch, base, axis, ux, vx, len, r1, r2, w) => {
    const first = pos.length / 3;
    for (let i = 0; i < rings; i++) {
      const x = i / (rings - 1), r = r1 + (r2 - r1) * x;
      for (let k = 0; k < sides; k++) {
        const th = (2 * Math.PI * k) / sides, c = Math.cos(th) * r, s = Math.sin(th) * r;
        pos.push(base[0] + axis[0] * len * x + ux[0] * c + vx[0] * s, base[1] + axis[1] * len * x + ux[1] * c + vx[1] * s, base[2] + axis[2] * len * x + ux[2] * c + vx[2] * s);
        ww.push(...w(x)); wb.push(branch);
      }
    }
    for (let i = 0; i + 1 < rings; i++) for (let k = 0; k < sides; k++) {
      const a = first + i * sides + k, b = first + i * sides + ((k + 1) % sides);
      idx.push(a, a + sides, b, b, a + sides, b + sides);
    }
  };
  tube(0, [0, 0, 0], [0, 1, 0], [1, 0, 0], [0, 0, 1], L[0], 0.06, 0.02, (x) => [x, 0, 0, 0]);
  tube(1, [0, 1, 0], [0, 0, 1], [1, 0, 0], [0, 1, 0], L[1], 0.02, 0.005, (x) => [0.5, x, 0, 0]);
  const B = new Builder();
  const attrs = { POSITION: B.add(new Float32Array(pos), 'VEC3', 5126, 34962, true), _WIND_W: B.add(new Float32Array(ww), 'VEC4', 5126, 34962), _WIND_BRANCH: B.add(new Float32Array(wb), 'SCALAR', 5126, 34962) };
  const ind = B.add(new Uint16Array(idx), 'SCALAR', 5123, 34963);
  const [c2a, c4a] = fit(1 / 3), [c2b, c4b] = fit(0.25);
  B.json.meshes = [{ name: 'fork', primitives: [{ attributes: attrs, indices: ind }] }];
  B.json.nodes = [{ name: 'fork', mesh: 0, extras: { sylva_wind: { version: 1, count: 2, parent: [-1, 0], level: [0, 1], anchor: [0, 0, 0, 0, 1, 0], axis: [0, 1, 0, 0, 0, 1], length: L, c2: [c2a, c2b], c4: [c4a, c4b], frequency: L.map((l) => 2.55 * l ** -0.59), stiffness: [1, 0] } } }];
  B.json.scenes = [{ nodes: [0] }]; B.json.scene = 0;
  writeFileSync(`${dir}/fork.glb`, B.finish());
}

// --- leaves: a 1 m quad facing +Z, double sided, lit from behind in the tests. ---
function leaf(hl2) {
  const B = new Builder();
  const pos = new Float32Array([-0.5, -0.5, 0, 0.5, -0.5, 0, 0.5, 0.5, 0, -0.5, 0.5, 0]);
  const nrm = new Float32Array([0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1]);
  const tan = new Float32Array([1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1]);
  const uv = new Float32Array([0, 1, 1, 1, 1, 0, 0, 0]);
  const attrs = { POSITION: B.add(pos, 'VEC3', 5126, 34962, true), NORMAL: B.add(nrm, 'VEC3', 5126, 34962), TANGENT: B.add(tan, 'VEC4', 5126, 34962), TEXCOORD_0: B.add(uv, 'VEC2', 5126, 34962) };
  const ind = B.add(new Uint16Array([0, 1, 2, 0, 2, 3]), 'SCALAR', 5123, 34963);
  const albedo = B.image(solidPng(4, 4, [90, 140, 50, 255]));
  B.json.samplers = [{ magFilter: 9729, minFilter: 9987, wrapS: 33071, wrapT: 33071 }];
  B.json.textures = [{ source: albedo, sampler: 0 }];
  const mat = { name: 'leaf', doubleSided: true, alphaMode: 'MASK', alphaCutoff: 0.5, pbrMetallicRoughness: { baseColorTexture: { index: 0 }, metallicFactor: 0, roughnessFactor: 0.6 },
    extensions: { KHR_materials_diffuse_transmission: { diffuseTransmissionFactor: 0.6, diffuseTransmissionColorFactor: [0.9, 1.0, 0.6] } } };
  B.json.extensionsUsed = ['KHR_materials_diffuse_transmission'];
  if (hl2) {
    // SYLVA_leaf_translucency (docs/leafmaps.md): h = decodeMin + texel (decodeMax - decodeMin),
    // adaxial (0.8, 0.6, 0.9) for light arriving on the normal side, abaxial (0.5, 0.7, 1.1).
    const enc = (h) => Math.round(((h + 1) / 4) * 255);
    const ad = B.image(solidPng(4, 4, [enc(0.8), enc(0.6), enc(0.9), 255]));
    const ab = B.image(solidPng(4, 4, [enc(0.5), enc(0.7), enc(1.1), 255]));
    B.json.textures.push({ source: ad, sampler: 0 }, { source: ab, sampler: 0 });
    mat.extensions.SYLVA_leaf_translucency = { adaxialTexture: { index: 1 }, abaxialTexture: { index: 2 }, decodeMin: -1, decodeMax: 3 };
    B.json.extensionsUsed.push('SYLVA_leaf_translucency');
  }
  B.json.materials = [mat];
  B.json.meshes = [{ name: 'leaf', primitives: [{ attributes: attrs, indices: ind, material: 0 }] }];
  B.json.nodes = [{ name: 'leaf', mesh: 0 }];
  B.json.scenes = [{ nodes: [0] }]; B.json.scene = 0;
  return B.finish();
}
writeFileSync(`${dir}/leaf_hl2.glb`, leaf(true));
writeFileSync(`${dir}/leaf_dt.glb`, leaf(false));

// --- lod.glb: boxes of 12, 12 x 4 and 12 x 16 triangles (subdivided faces) as LOD2..LOD0. ---
{
  const B = new Builder();
  const meshes = [];
  for (const n of [4, 2, 1]) {
    const pos = [], idx = [];
    // Each face of the unit box (1 m, base at y = 0) as an n x n grid.
    const faces = [[0, 1, 2, 1], [0, 1, 2, -1], [1, 2, 0, 1], [1, 2, 0, -1], [2, 0, 1, 1], [2, 0, 1, -1]];
    for (const [a, b, c, s] of faces) {
      const base = pos.length / 3;
      for (let i = 0; i <= n; i++) for (let j = 0; j <= n; j++) { const p = [0, 0, 0]; p[a] = i / n - 0.5; p[b] = j / n - 0.5; p[c] = 0.5 * s; p[1] += 0.5; pos.push(...p); }
      for (let i = 0; i < n; i++) for (let j = 0; j < n; j++) { const q = base + i * (n + 1) + j; if (s > 0) idx.push(q, q + n + 1, q + 1, q + 1, q + n + 1, q + n + 2); else idx.push(q, q + 1, q + n + 1, q + 1, q + n + 2, q + n + 1); }
    }
    const attrs = { POSITION: B.add(new Float32Array(pos), 'VEC3', 5126, 34962, true) };
    meshes.push({ name: `box${n}`, primitives: [{ attributes: attrs, indices: B.add(new Uint16Array(idx), 'SCALAR', 5123, 34963) }] });
  }
  B.json.meshes = meshes;
  B.json.extensionsUsed = ['MSFT_lod'];
  B.json.nodes = [
    { name: 'box_LOD0', mesh: 0, extensions: { MSFT_lod: { ids: [1, 2] } }, extras: { MSFT_screencoverage: [0.5, 0.2, 0.05] } },
    { name: 'box_LOD1', mesh: 1 }, { name: 'box_LOD2', mesh: 2 }];
  B.json.scenes = [{ nodes: [0] }]; B.json.scene = 0;
  writeFileSync(`${dir}/lod.glb`, B.finish());
}

// --- nomesh.glb and missing_texture.gltf ---
{
  const B = new Builder();
  B.add(new Float32Array([0, 0, 0]), 'VEC3', 5126, 0, true);
  B.json.nodes = [{ name: 'empty' }]; B.json.scenes = [{ nodes: [0] }]; B.json.scene = 0;
  writeFileSync(`${dir}/nomesh.glb`, B.finish());
  const pos = Buffer.from(new Float32Array([0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1]).buffer);
  const g = { asset: { version: '2.0' }, buffers: [{ byteLength: pos.length, uri: `data:application/octet-stream;base64,${pos.toString('base64')}` }],
    bufferViews: [{ buffer: 0, byteOffset: 0, byteLength: 36 }, { buffer: 0, byteOffset: 36, byteLength: 24 }],
    accessors: [{ bufferView: 0, componentType: 5126, count: 3, type: 'VEC3', min: [0, 0, 0], max: [1, 1, 0] }, { bufferView: 1, componentType: 5126, count: 3, type: 'VEC2' }],
    images: [{ uri: 'missing.png' }], textures: [{ source: 0 }], materials: [{ pbrMetallicRoughness: { baseColorTexture: { index: 0 } } }],
    meshes: [{ primitives: [{ attributes: { POSITION: 0, TEXCOORD_0: 1 }, material: 0 }] }], nodes: [{ mesh: 0 }], scenes: [{ nodes: [0] }], scene: 0 };
  writeFileSync(`${dir}/missing_texture.gltf`, JSON.stringify(g));
}
