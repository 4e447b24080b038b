// Renders a glb's silhouette with three.js in headless Chromium (three_mask.html), with the
// camera the viewer reported (sylva view --json): node three_render.mjs FILE.glb VIEW.json OUT.png
import { createServer } from 'node:http';
import { readFileSync, existsSync, statSync } from 'node:fs';
import { spawn } from 'node:child_process';
import { resolve, extname } from 'node:path';

const [glb, viewJson, out] = process.argv.slice(2);
const v = JSON.parse(readFileSync(viewJson, 'utf8'));
const root = resolve(process.env.SYLVA_SOURCE_DIR || '.');
const types = { '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript', '.glb': 'model/gltf-binary' };
const server = createServer((req, res) => {
  const url = decodeURIComponent(req.url.split('?')[0]);
  const path = url === '/model.glb' ? resolve(glb) : resolve(root, '.' + url);
  if ((url !== '/model.glb' && !path.startsWith(root)) || !existsSync(path) || !statSync(path).isFile()) { res.writeHead(404); res.end(); return; }
  res.writeHead(200, { 'Content-Type': types[extname(path)] || 'application/octet-stream' });
  res.end(readFileSync(path));
});
server.listen(0, '127.0.0.1', () => {
  const port = server.address().port;
  const far = v.camera[2] * 4 + 1000;
  const qs = `glb=/model.glb&w=${v.width}&h=${v.height}&fovy=${v.fovy_deg}&near=${v.near}&far=${far}&eye=${v.eye.join(',')}&target=${v.target.join(',')}`;
  const chrome = spawn(process.env.CHROMIUM || 'chromium', [
    '--headless=new', '--no-sandbox', '--disable-dev-shm-usage', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--hide-scrollbars', '--force-device-scale-factor=1', `--window-size=${v.width},${v.height}`,
    '--virtual-time-budget=60000', '--run-all-compositor-stages-before-draw', `--screenshot=${resolve(out)}`,
    `http://127.0.0.1:${port}/tests/viewer/three_mask.html?${qs}`], { stdio: ['ignore', 'ignore', 'pipe'] });
  let err = '';
  chrome.stderr.on('data', (d) => { err += d; });
  const timer = setTimeout(() => chrome.kill('SIGKILL'), 240000);
  chrome.on('exit', (code) => {
    clearTimeout(timer);
    server.close();
    if (code !== 0 || !existsSync(out)) { console.error(`chromium failed (${code}): ${err.slice(-400)}`); process.exit(1); }
  });
});
