// Renders a glb's silhouette with three.js in headless Chromium (three_mask.html), with the
// camera the viewer reported (sylva view --json): node three_render.mjs FILE.glb VIEW.json OUT.png
import { createServer } from 'node:http';
import { readFileSync, existsSync, statSync, unlinkSync } from 'node:fs';
import { spawn } from 'node:child_process';
import { resolve, extname } from 'node:path';
import { readPng, mask } from './png.mjs';

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
// Headless Chromium now and then hangs before it takes the screenshot (seen once in a
// clean-clone run: killed after 240 s, while the same render takes 4 s alone), or takes it
// before the page has drawn (seen once: an all-black picture, 0 of the viewer's 3425 pixels,
// on a loaded machine; --virtual-time-budget does not wait for the textures' off-thread
// decoding). That is the browser failing, not the comparison: the render is tried up to three
// times, 90 s each, and a run that never produced a drawn picture fails with the browser's
// last words (an empty one is kept, and the comparison fails on it).
const ATTEMPTS = 3, ATTEMPT_MS = 90000;
server.listen(0, '127.0.0.1', () => {
  const port = server.address().port;
  const far = v.camera[2] * 4 + 1000;
  const qs = `glb=/model.glb&w=${v.width}&h=${v.height}&fovy=${v.fovy_deg}&near=${v.near}&far=${far}&eye=${v.eye.join(',')}&target=${v.target.join(',')}`;
  const attempt = (k) => {
    if (existsSync(out)) unlinkSync(out);
    const chrome = spawn(process.env.CHROMIUM || 'chromium', [
      '--headless=new', '--no-sandbox', '--disable-dev-shm-usage', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
      '--hide-scrollbars', '--force-device-scale-factor=1', `--window-size=${v.width},${v.height}`,
      '--virtual-time-budget=60000', '--run-all-compositor-stages-before-draw', `--screenshot=${resolve(out)}`,
      `http://127.0.0.1:${port}/tests/viewer/three_mask.html?${qs}`], { stdio: ['ignore', 'ignore', 'pipe'] });
    let err = '';
    chrome.stderr.on('data', (d) => { err += d; });
    const timer = setTimeout(() => chrome.kill('SIGKILL'), ATTEMPT_MS);
    chrome.on('exit', (code) => {
      clearTimeout(timer);
      let drawn = false;
      if (code === 0 && existsSync(out)) {
        try { drawn = mask(readPng(out)).some((v) => v); } catch { drawn = false; }
        if (drawn || k + 1 >= ATTEMPTS) { server.close(); return; }
        console.error(`chromium attempt ${k + 1} took its screenshot before the page drew; trying again`);
        attempt(k + 1);
        return;
      }
      if (k + 1 < ATTEMPTS) { console.error(`chromium attempt ${k + 1} failed (${code}); trying again`); attempt(k + 1); return; }
      server.close();
      console.error(`chromium failed (${code}) ${ATTEMPTS} times: ${err.slice(-400)}`);
      process.exit(1);
    });
  };
  attempt(0);
});
