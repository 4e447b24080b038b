// Renders Sylva .glb files as a game engine would: three.js (npm `three`, GLTFLoader) in
// Debian's headless Chromium, driven over the DevTools protocol. A small HTTP server serves
// the page (tests/three/render.html), node_modules/three and the files.
// Usage: node --experimental-websocket tests/three/render_glb.mjs [options] FILE.glb...
//   --lod N|all  level to draw (all: every level of each file; default 0)
//   --view front|side|persp|close   front/side: orthographic, framed like the impostor atlas
//   --size PX    image height (default 256)   --png PREFIX  write PREFIX<name>_lod<N>_<view>.png
//   --at X,Y,Z,R close-up centre and radius (glTF frame)   --bark-only 1  hide the leaf cards
// Prints one JSON line per render: {file, lod, view, errors, warnings, triangles, coverage,
// impostor_iou, ...}. Exit 0 when every page finished, 3 when the browser failed.
import { spawn } from 'node:child_process';
import { createServer } from 'node:http';
import { readFileSync, writeFileSync, mkdtempSync, rmSync, statSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, resolve, basename, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url)), repo = resolve(here, '../..');
const args = process.argv.slice(2), files = [];
const opt = { lod: '0', view: 'persp', size: '256', png: '', at: '' };
for (let i = 0; i < args.length; i++) {
  if (args[i].startsWith('--')) opt[args[i].slice(2)] = args[++i];
  else files.push(resolve(args[i]));
}
const types = { '.html': 'text/html', '.mjs': 'text/javascript', '.js': 'text/javascript', '.glb': 'model/gltf-binary' };
const server = createServer((req, res) => {
  const url = new URL(req.url, 'http://x');
  let path = url.pathname.startsWith('/file/') ? decodeURIComponent(url.pathname.slice(5)) : join(repo, decodeURIComponent(url.pathname));
  try {
    const body = readFileSync(path);
    res.writeHead(200, { 'content-type': types[path.slice(path.lastIndexOf('.'))] || 'application/octet-stream', 'cache-control': 'no-store' });
    res.end(body);
  } catch { res.writeHead(404); res.end(); }
});
await new Promise(r => server.listen(0, '127.0.0.1', r));
const port = server.address().port;
// Chromium's profile goes when this process exits, however it exits.
const profile = mkdtempSync(join(tmpdir(), 'sylva-three-'));
process.on('exit', () => { try { rmSync(profile, { recursive: true, force: true, maxRetries: 3 }); } catch { /* chromium still writing: left to /tmp's cleaner */ } });
const browser = spawn('chromium', ['--headless', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--hide-scrollbars', '--mute-audio', '--no-first-run', '--disable-extensions', '--remote-debugging-port=0',
  `--user-data-dir=${profile}`, 'about:blank'], { stdio: ['ignore', 'ignore', 'pipe'] });
const fail = (msg) => { console.error(`render_glb: ${msg}`); browser.kill(); server.close(); process.exit(3); };
const wsUrl = await new Promise((res, rej) => {
  let buf = '';
  browser.stderr.on('data', d => { buf += d; const m = buf.match(/DevTools listening on (ws:\S+)/); if (m) res(m[1]); });
  browser.on('exit', () => rej(new Error('chromium exited')));
  setTimeout(() => rej(new Error('chromium did not start')), 30000);
}).catch(e => fail(e.message));
const version = await (await fetch(wsUrl.replace('ws://', 'http://').replace(/\/devtools\/.*/, '/json/version'))).json();
const targets = await (await fetch(wsUrl.replace('ws://', 'http://').replace(/\/devtools\/.*/, '/json/list'))).json();
const page = targets.find(t => t.type === 'page');
const ws = new WebSocket(page.webSocketDebuggerUrl);
await new Promise(r => ws.addEventListener('open', r));
let nextId = 1;
const pending = new Map(), events = [];
ws.addEventListener('message', ev => {
  const m = JSON.parse(ev.data);
  if (m.id && pending.has(m.id)) { pending.get(m.id)(m); pending.delete(m.id); }
  else if (m.method) events.push(m);
});
const send = (method, params = {}) => new Promise(r => { const id = nextId++; pending.set(id, r); ws.send(JSON.stringify({ id, method, params })); });
await send('Runtime.enable');
await send('Page.enable');
const sleep = ms => new Promise(r => setTimeout(r, ms));

async function render(file, lod, view) {
  const size = +opt.size, w = view === 'front' || view === 'side' ? size / 2 : size;
  await send('Emulation.setDeviceMetricsOverride', { width: w, height: size, deviceScaleFactor: 1, mobile: false });
  events.length = 0;
  let url = `http://127.0.0.1:${port}/tests/three/render.html?glb=/file${encodeURI(file)}&lod=${lod}&view=${view}&size=${size}`;
  if (opt['bark-only']) url += '&bark=1';
  if (opt.at) { const [x, y, z, r] = opt.at.split(','); url += `&x=${x}&y=${y}&z=${z}&r=${r}`; }
  await send('Page.navigate', { url });
  let verdict = null;
  for (let t = 0; t < 1200 && !verdict; t++) {
    await sleep(100);
    const r = await send('Runtime.evaluate', { expression: 'JSON.stringify(window.__verdict || null)', returnByValue: true });
    verdict = JSON.parse((r.result && r.result.result && r.result.result.value) || 'null');
  }
  if (!verdict) return { file: basename(file), lod, view, errors: ['page did not finish in 120 s'] };
  for (const e of events) if (e.method === 'Runtime.exceptionThrown') verdict.errors.push(e.params.exceptionDetails.text);
  if (opt.png) {
    const shot = await send('Page.captureScreenshot', { format: 'png' });
    const name = `${opt.png}${basename(file, '.glb')}_lod${lod}_${view}.png`;
    writeFileSync(name, Buffer.from(shot.result.data, 'base64'));
    verdict.png = name;
  }
  return { file: basename(file), browser: version.Browser, ...verdict };
}

for (const f of files) {
  try { statSync(f); } catch { fail(`${f}: no such file`); }
  if (opt.lod === 'all') {
    const first = await render(f, 0, opt.view);
    console.log(JSON.stringify(first));
    for (let l = 1; l < (first.levels || 1); l++) console.log(JSON.stringify(await render(f, l, opt.view)));
  } else {
    console.log(JSON.stringify(await render(f, +opt.lod, opt.view)));
  }
}
ws.close();
browser.kill();
server.close();
