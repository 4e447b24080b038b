// See render.html. Everything the page reports goes into #out as JSON.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';

const q = new URLSearchParams(location.search);
const size = +(q.get('size') || 256), lodWanted = +(q.get('lod') || 0), view = q.get('view') || 'front';
const verdict = { errors: [], warnings: [], lod: lodWanted, view };
const out = document.getElementById('out');
for (const kind of ['error', 'warn']) {
  const orig = console[kind].bind(console);
  console[kind] = (...a) => { (kind === 'error' ? verdict.errors : verdict.warnings).push(a.map(String).join(' ')); orig(...a); };
}
addEventListener('error', e => verdict.errors.push(String(e.message)));
addEventListener('unhandledrejection', e => verdict.errors.push(String(e.reason)));
const finish = () => { out.textContent = JSON.stringify(verdict); window.__verdict = verdict; };

function mask(pixels, w, h, threshold) {
  const m = new Uint8Array(w * h);
  for (let i = 0; i < w * h; i++) m[i] = pixels[4 * i + 3] >= threshold ? 1 : 0;
  return m;
}
// Covered where anything was drawn over the magenta clear colour.
function drawn(pixels, w, h) {
  const m = new Uint8Array(w * h);
  for (let i = 0; i < w * h; i++)
    m[i] = Math.abs(pixels[4 * i] - 255) + pixels[4 * i + 1] + Math.abs(pixels[4 * i + 2] - 255) > 24 ? 1 : 0;
  return m;
}
function iou(a, b) {
  let i = 0, u = 0;
  for (let k = 0; k < a.length; k++) { i += a[k] & b[k]; u += a[k] | b[k]; }
  return u ? i / u : 1;
}
function meanColour(pixels, m) {
  const s = [0, 0, 0]; let n = 0;
  for (let k = 0; k < m.length; k++) if (m[k]) { for (let c = 0; c < 3; c++) s[c] += pixels[4 * k + c]; n++; }
  return s.map(v => (n ? v / n / 255 : 0));
}
function triangles(obj) {
  let t = 0;
  obj.traverse(o => {
    if (!o.isMesh) return;
    const g = o.geometry, n = g.index ? g.index.count / 3 : g.attributes.position.count / 3;
    t += n * (o.isInstancedMesh ? o.count : 1);
  });
  return t;
}

async function main() {
  const renderer = new THREE.WebGLRenderer({ antialias: false, alpha: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  const gltf = await new GLTFLoader().loadAsync(q.get('glb'));
  const parser = gltf.parser, json = parser.json;
  const root = json.nodes[json.scenes[json.scene || 0].nodes[0]];
  const ids = [json.scenes[json.scene || 0].nodes[0], ...((root.extensions || {}).MSFT_lod || { ids: [] }).ids];
  verdict.levels = ids.length;
  const groups = [];
  for (const id of ids) groups.push(await parser.getDependency('node', id));
  verdict.triangles = groups.map(triangles);
  const impostor = groups[groups.length - 1];
  let impMesh = null;
  impostor.traverse(o => { if (o.isMesh && o.material && o.material.name === 'impostor') impMesh = o; });
  const lod = groups[Math.min(lodWanted, groups.length - 1)];
  const scene = new THREE.Scene();
  scene.add(new THREE.HemisphereLight(0xcfe3ff, 0x4a3b2a, 1.2));
  const sun = new THREE.DirectionalLight(0xfff4e0, 2.2);
  sun.position.set(0.4, 1.0, 0.6);
  scene.add(sun);
  scene.add(lod);
  if (q.get('bark') === '1') lod.traverse(o => { if (o.isInstancedMesh) o.visible = false; });
  // Framing: the impostor card's box (the tree's bounds plus 3 %), as the atlas was drawn.
  const box = new THREE.Box3();
  if (impMesh) { impMesh.geometry.computeBoundingBox(); box.copy(impMesh.geometry.boundingBox); }
  else box.setFromObject(lod);
  const c = box.getCenter(new THREE.Vector3()), ext = box.getSize(new THREE.Vector3());
  let cam, w = size, h = size;
  if (view === 'close') {
    // A junction close-up: where the first child leaves the trunk.
    const at = new THREE.Vector3(+q.get('x') || c.x, +q.get('y') || ext.y * 0.3, +q.get('z') || c.z);
    const r = +(q.get('r') || ext.y * 0.08);
    cam = new THREE.PerspectiveCamera(40, 1, r * 0.05, r * 40);
    cam.position.set(at.x + r * 1.6, at.y + r * 0.8, at.z + r * 2.2);
    cam.lookAt(at);
  } else if (view === 'front' || view === 'side') {
    // The atlas halves: along -Z (x to the right) and along -X (-z to the right), each
    // half as wide as the atlas is high: the same non-uniform scale, so pixels line up.
    w = size / 2;
    cam = new THREE.OrthographicCamera(-1, 1, 1, -1, -1e4, 1e4);
    if (view === 'front') { cam.left = box.min.x; cam.right = box.max.x; cam.position.set(0, 0, box.max.z + 10); cam.lookAt(0, 0, -1e6); }
    else { cam.left = -box.max.z; cam.right = -box.min.z; cam.position.set(box.max.x + 10, 0, 0); cam.lookAt(-1e6, 0, 0); }
    cam.top = box.max.y; cam.bottom = box.min.y;
    cam.position.y = 0;
    cam.updateProjectionMatrix();
  } else {
    cam = new THREE.PerspectiveCamera(35, 1, 0.05, 1e4);
    const d = Math.max(ext.x, ext.y) * 1.9;
    cam.position.set(c.x + d * 0.55, c.y + ext.y * 0.05, c.z + d * 0.85);
    cam.lookAt(c);
  }
  document.body.appendChild(renderer.domElement);
  // The mask render clears to pure magenta, a colour no bark or leaf has.
  renderer.setClearColor(0xff00ff, 1);
  const readMask = (mw, mh) => {
    renderer.setSize(mw, mh);
    renderer.render(scene, cam);
    const gl = renderer.getContext(), px = new Uint8Array(4 * mw * mh);
    gl.readPixels(0, 0, mw, mh, gl.RGBA, gl.UNSIGNED_BYTE, px);
    // readPixels is bottom-up; flip to image rows.
    const flip = new Uint8Array(px.length);
    for (let y = 0; y < mh; y++) flip.set(px.subarray(4 * mw * (mh - 1 - y), 4 * mw * (mh - y)), 4 * mw * y);
    return { px: flip, m: drawn(flip, mw, mh) };
  };
  if (impMesh && (view === 'front' || view === 'side')) {
    // Agreement with the atlas, on the atlas's own pixel grid. The atlas
    // rasteriser is conservative (a pixel a triangle touches counts) and
    // samples the leaf texture without mip-maps; a GPU render at the atlas's
    // size misses every leaf card thinner than a pixel and thins alpha-tested
    // cards through the mip chain, so the crown would read as half empty
    // (IoU ~0.2 at 128 px). Rendering at SS times the atlas resolution and
    // counting a texel covered when any of its SS x SS samples is brings the
    // GPU's coverage to the same definition.
    const img = impMesh.material.map.image, SS = 4;
    const aw = img.width / 2, ah = img.height, hi = readMask(aw * SS, ah * SS);
    const mg = new Uint8Array(aw * ah);
    for (let y = 0; y < ah * SS; y++)
      for (let x = 0; x < aw * SS; x++) if (hi.m[y * aw * SS + x]) mg[((y / SS) | 0) * aw + ((x / SS) | 0)] = 1;
    const cv = new OffscreenCanvas(aw, ah), cx = cv.getContext('2d');
    cx.drawImage(img, view === 'front' ? 0 : aw, 0, aw, ah, 0, 0, aw, ah);
    const ip = cx.getImageData(0, 0, aw, ah).data, mi = mask(ip, aw, ah, 128);
    verdict.impostor_iou = iou(mg, mi);
    verdict.impostor_colour = meanColour(ip, mi);
    // LOD0's colour at the same supersampling: at the atlas's own size the
    // GPU keeps mostly bark (it drops cards thinner than a pixel).
    verdict.lod0_colour = meanColour(hi.px, hi.m);
    if (lodWanted === 0 && groups.length > 1) {
      // The impostor level as the engine draws it, same lights, camera and
      // supersampling: what a viewer sees when the tree switches to it.
      scene.remove(lod);
      scene.add(impostor);
      const im = readMask(aw * SS, ah * SS);
      verdict.impostor_render_colour = meanColour(im.px, im.m);
      scene.remove(impostor);
      scene.add(lod);
    }
    verdict.atlas_coverage = mi.reduce((a, b) => a + b, 0) / (aw * ah);
  }
  const lo = readMask(w, h);
  verdict.coverage = lo.m.reduce((a, b) => a + b, 0) / (w * h);
  verdict.mean_colour = meanColour(lo.px, lo.m);

  renderer.setClearColor(0xb9cfe0, 1);
  renderer.render(scene, cam);
}
main().then(finish, e => { verdict.errors.push(String(e && e.stack || e)); finish(); });
