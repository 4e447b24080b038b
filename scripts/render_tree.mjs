// Renders a tree asset (.glb, LOD0 as the scene holds it) next to its scan
// (points, world coordinates, Z up) with three.js in headless Chromium.
//   node scripts/render_tree.mjs --glb tree.glb [--points scan.xyz] --out view.png
//        [--title TEXT] [--size 1400x700] [--azimuth DEG] [--elevation DEG]
// The glb's asset.extras.origin places the asset in the scan's frame
// (world = origin + (x, -z, y)); both panels share one orthographic camera.
import http from 'node:http';
import fs from 'node:fs';
import path from 'node:path';
import { spawn } from 'node:child_process';
import { fileURLToPath } from 'node:url';

const args = Object.fromEntries(process.argv.slice(2).reduce((a, v, i, all) => {
  if (v.startsWith('--')) a.push([v.slice(2), all[i + 1] && !all[i + 1].startsWith('--') ? all[i + 1] : '1']);
  return a;
}, []));
if (!args.glb || !args.out) {
  console.error('usage: node scripts/render_tree.mjs --glb TREE.glb [--points SCAN.xyz] --out OUT.png');
  process.exit(1);
}
const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const [W, H] = (args.size || '1400x700').split('x').map(Number);
const glb = fs.readFileSync(args.glb);
let pts = new Float32Array(0);
if (args.points) {
  const txt = fs.readFileSync(args.points, 'utf8').split('\n');
  const a = [];
  for (const line of txt) {
    const f = line.trim().split(/[\s,;]+/).map(Number);
    if (f.length >= 3 && f.every((x, k) => k > 2 || Number.isFinite(x))) a.push(f[0], f[1], f[2]);
  }
  pts = new Float32Array(a);
}
const page = `<!doctype html><html><head><style>body{margin:0;background:#fff}</style>
<script type="importmap">{"imports":{"three":"/three/build/three.module.js","three/addons/":"/three/examples/jsm/"}}</script>
</head><body><script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
const W=${W}, H=${H}, title=${JSON.stringify(args.title || '')};
const renderer = new THREE.WebGLRenderer({antialias:true, preserveDrawingBuffer:true});
renderer.setSize(W, H); renderer.setScissorTest(true); document.body.appendChild(renderer.domElement);
const glb = await (await fetch('/data/tree.glb')).arrayBuffer();
const ptsBuf = new Float32Array(await (await fetch('/data/points.bin')).arrayBuffer());
const gltf = await new GLTFLoader().parseAsync(glb, '');
const origin = (gltf.asset && gltf.asset.extras && gltf.asset.extras.origin) || [0,0,0];
const sceneA = new THREE.Scene(), sceneB = new THREE.Scene();
sceneA.background = new THREE.Color(0xffffff); sceneB.background = new THREE.Color(0xffffff);
for (const s of [sceneA, sceneB]) {
  s.add(new THREE.HemisphereLight(0xffffff, 0x445533, 1.6));
  const d = new THREE.DirectionalLight(0xffffff, 2.2); d.position.set(3, 6, 4); s.add(d);
}
sceneB.add(gltf.scene);
const box = new THREE.Box3().setFromObject(gltf.scene);
if (ptsBuf.length) {
  const p = new Float32Array(ptsBuf.length), c = new Float32Array(ptsBuf.length);
  let zmin = Infinity, zmax = -Infinity;
  for (let i = 0; i < ptsBuf.length; i += 3) { zmin = Math.min(zmin, ptsBuf[i+2]); zmax = Math.max(zmax, ptsBuf[i+2]); }
  for (let i = 0; i < ptsBuf.length; i += 3) {
    p[i] = ptsBuf[i] - origin[0]; p[i+1] = ptsBuf[i+2] - origin[2]; p[i+2] = -(ptsBuf[i+1] - origin[1]);
    const t = (ptsBuf[i+2] - zmin) / Math.max(1e-6, zmax - zmin);
    c[i] = 0.35 - 0.15 * t; c[i+1] = 0.3 + 0.3 * t; c[i+2] = 0.15;
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(p, 3)); g.setAttribute('color', new THREE.BufferAttribute(c, 3));
  const cloud = new THREE.Points(g, new THREE.PointsMaterial({size: 2, sizeAttenuation: false, vertexColors: true}));
  sceneA.add(cloud);
  box.union(new THREE.Box3().setFromObject(cloud));
}
const ctr = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3());
const half = Math.max(size.x, size.y, size.z) * 0.55, aspect = (ptsBuf.length ? W / 2 : W) / H;
const cam = new THREE.OrthographicCamera(-half * aspect, half * aspect, half, -half, 0.01, 10 * half + 100);
const az = ${Number(args.azimuth || 0)} * Math.PI / 180, el = ${Number(args.elevation || 8)} * Math.PI / 180;
cam.position.set(ctr.x + Math.sin(az) * Math.cos(el) * 5 * half, ctr.y + Math.sin(el) * 5 * half, ctr.z + Math.cos(az) * Math.cos(el) * 5 * half);
cam.lookAt(ctr);
const panels = ptsBuf.length ? [[sceneA, 0], [sceneB, W / 2]] : [[sceneB, 0]];
const pw = ptsBuf.length ? W / 2 : W;
for (const [s, x] of panels) { renderer.setViewport(x, 0, pw, H); renderer.setScissor(x, 0, pw, H); renderer.render(s, cam); }
const out = document.createElement('canvas'); out.width = W; out.height = H;
const ctx = out.getContext('2d'); ctx.drawImage(renderer.domElement, 0, 0);
ctx.fillStyle = '#222'; ctx.font = '18px sans-serif';
if (ptsBuf.length) { ctx.fillText('scan', 12, 26); ctx.fillText('asset (LOD0)', W / 2 + 12, 26); }
if (title) ctx.fillText(title, 12, H - 14);
await fetch('/done', {method: 'POST', body: out.toDataURL('image/png')});
</script></body></html>`;
const done = new Promise((resolve, reject) => {
  const server = http.createServer((req, res) => {
    if (req.url === '/') { res.writeHead(200, {'content-type': 'text/html'}); return res.end(page); }
    if (req.url === '/data/tree.glb') { res.writeHead(200); return res.end(glb); }
    if (req.url === '/data/points.bin') { res.writeHead(200); return res.end(Buffer.from(pts.buffer)); }
    if (req.url === '/done') {
      const chunks = [];
      req.on('data', (c) => chunks.push(c));
      req.on('end', () => { res.end('ok'); resolve([server, Buffer.concat(chunks).toString()]); });
      return;
    }
    const f = path.join(root, 'node_modules', decodeURIComponent(req.url));
    if (!f.startsWith(path.join(root, 'node_modules')) || !fs.existsSync(f)) { res.writeHead(404); return res.end(); }
    res.writeHead(200, {'content-type': f.endsWith('.js') ? 'text/javascript' : 'application/octet-stream'});
    res.end(fs.readFileSync(f));
  });
  server.listen(0, '127.0.0.1', () => {
    const port = server.address().port;
    const ch = spawn('chromium', ['--headless=new', '--no-sandbox', '--disable-gpu-sandbox', '--use-angle=swiftshader',
      '--enable-unsafe-swiftshader', `--window-size=${W},${H}`, `http://127.0.0.1:${port}/`], {stdio: 'ignore'});
    server.chromium = ch;
    setTimeout(() => reject(new Error('render timed out')), 120000);
  });
});
try {
  const [server, url] = await done;
  fs.writeFileSync(args.out, Buffer.from(url.split(',')[1], 'base64'));
  server.chromium.kill();
  server.close();
  process.exit(0);
} catch (e) {
  console.error(`render_tree: ${e.message}`);
  process.exit(3);
}
