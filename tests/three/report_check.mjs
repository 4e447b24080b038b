// Opens a batch's report.html from file:// (as a user double-clicking it would) in Debian's
// headless Chromium over the DevTools protocol, waits for the page's three.js loader, opens
// the 3D preview of each tree (or the first --max), and prints one JSON line:
//   {ready, errors, thumbnails, placeholders, trees: [{id, errors, triangles, coverage}], png}
// Usage: node --experimental-websocket tests/three/report_check.mjs OUTDIR/report.html
//          [--max N] [--png FILE] [--width PX] [--height PX] [--preview ID]
// --png: a screenshot of the page with the preview of --preview (default: the first tree) open.
// Exit 0 when the page answered, 3 when the browser failed.
import { spawn } from 'node:child_process';
import { writeFileSync, mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';

const args = process.argv.slice(2);
const opt = { max: '1000', png: '', width: '1400', height: '1000', preview: '' };
let page = '';
for (let i = 0; i < args.length; i++) {
  if (args[i].startsWith('--')) opt[args[i].slice(2)] = args[++i];
  else page = resolve(args[i]);
}
// Chromium's profile goes when this process exits, however it exits.
const profile = mkdtempSync(join(tmpdir(), 'sylva-report-'));
process.on('exit', () => { try { rmSync(profile, { recursive: true, force: true, maxRetries: 3 }); } catch { /* chromium still writing: left to /tmp's cleaner */ } });
const browser = spawn('chromium', ['--headless', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--hide-scrollbars', '--mute-audio', '--no-first-run', '--disable-extensions', '--remote-debugging-port=0',
  `--user-data-dir=${profile}`, 'about:blank'], { stdio: ['ignore', 'ignore', 'pipe'] });
const fail = (msg) => { console.error(`report_check: ${msg}`); browser.kill(); process.exit(3); };
const wsUrl = await new Promise((res, rej) => {
  let buf = '';
  browser.stderr.on('data', d => { buf += d; const m = buf.match(/DevTools listening on (ws:\S+)/); if (m) res(m[1]); });
  browser.on('exit', () => rej(new Error('chromium exited')));
  setTimeout(() => rej(new Error('chromium did not start')), 30000);
}).catch(e => fail(e.message));
const targets = await (await fetch(wsUrl.replace('ws://', 'http://').replace(/\/devtools\/.*/, '/json/list'))).json();
const ws = new WebSocket(targets.find(t => t.type === 'page').webSocketDebuggerUrl);
await new Promise(r => ws.addEventListener('open', r));
let nextId = 1;
const pending = new Map(), events = [];
ws.addEventListener('message', ev => {
  const m = JSON.parse(ev.data);
  if (m.id && pending.has(m.id)) { pending.get(m.id)(m); pending.delete(m.id); }
  else if (m.method) events.push(m);
});
const send = (method, params = {}) => new Promise(r => { const id = nextId++; pending.set(id, r); ws.send(JSON.stringify({ id, method, params })); });
const sleep = ms => new Promise(r => setTimeout(r, ms));
const evaluate = async (expression, awaitPromise = false) => {
  const r = await send('Runtime.evaluate', { expression, returnByValue: true, awaitPromise });
  return r.result && r.result.result ? r.result.result.value : undefined;
};
await send('Runtime.enable');
await send('Page.enable');
await send('Emulation.setDeviceMetricsOverride', { width: +opt.width, height: +opt.height, deviceScaleFactor: 1, mobile: false });
await send('Page.navigate', { url: 'file://' + page });
let state = null;
for (let t = 0; t < 1200 && !(state && state.ready); t++) {
  await sleep(100);
  state = JSON.parse((await evaluate('JSON.stringify(window.__sylvaReport || null)')) || 'null');
}
if (!state || !state.ready) fail('the page did not finish loading in 120 s');
const verdict = JSON.parse(await evaluate(`JSON.stringify({
  ready: true, errors: window.__sylvaReport.errors,
  status: (document.getElementById('preview-status') || {}).textContent,
  thumbnails: [...document.querySelectorAll('.card img')].filter(i => i.complete && i.naturalWidth > 0).length,
  broken: [...document.querySelectorAll('.card img')].filter(i => !(i.complete && i.naturalWidth > 0)).length,
  placeholders: document.querySelectorAll('.card .ph').length,
  ids: [...document.querySelectorAll('button[data-tree]')].map(b => b.dataset.tree),
  sections: [...document.querySelectorAll('section')].map(s => s.id)})`));
verdict.trees = [];
const ids = verdict.ids.slice(0, +opt.max);
for (const id of ids) {
  const v = await evaluate(`window.sylvaPreview ? sylvaPreview(${JSON.stringify(id)}).then(v => JSON.stringify(v)) : JSON.stringify({id: ${JSON.stringify(id)}, errors: ['no preview function']})`, true);
  verdict.trees.push(JSON.parse(v || '{"errors":["no answer"]}'));
}
for (const e of events) if (e.method === 'Runtime.exceptionThrown') verdict.errors.push(e.params.exceptionDetails.text);
if (opt.png) {
  const id = opt.preview || ids[0];
  if (id) await evaluate(`sylvaPreview(${JSON.stringify(id)}).then(() => 1)`, true);
  await sleep(300);
  const shot = await send('Page.captureScreenshot', { format: 'png', captureBeyondViewport: false });
  writeFileSync(opt.png, Buffer.from(shot.result.data, 'base64'));
  verdict.png = opt.png;
}
delete verdict.ids;
console.log(JSON.stringify(verdict));
ws.close();
browser.kill();
process.exit(0);
