// Checks for tests/test_viewer_cli.sh, each printing one line and exiting 1 on failure.
//   node check.mjs beam DUMP.csv BEAM.json          profile vs the analytic cantilever, within 1 %
//   node check.mjs linear DUMP_A.csv DUMP_B.csv K    B's deflection = K x A's, within 1 %
//   node check.mjs wind REST_OR_T0.csv T1.csv HEIGHT MAXFRAC   max displacement between two dumps <= MAXFRAC x HEIGHT
//   node check.mjs moves DUMP.csv HEIGHT MINFRAC    some vertex moved >= MINFRAC x HEIGHT
//   node check.mjs fork DUMP.csv                    the child's base ring moves with the trunk's ring at the attachment
//   node check.mjs bbox MASK.png VIEW.json TOL MINW MINH   silhouette inside the projected bounding box, spanning it
//   node check.mjs iou A.png B.png MIN              mask IoU
//   node check.mjs brighter ON.png OFF.png          centre pixel of ON brighter than OFF
//   node check.mjs mean_brighter ON.png OFF.png MASK.png   ON brighter (by 2 %) than OFF over the mask
//   node check.mjs hl2 SHOT.png VIEW.json TOL       centre radiance vs the HL2 reconstruction (eq. 3.23)
import { readFileSync } from 'node:fs';
import { readPng, mask } from './png.mjs';

const [what, ...a] = process.argv.slice(2);
const fail = (m) => { console.log(`FAIL: ${m}`); process.exit(1); };
const ok = (m) => console.log(m);
const csv = (p) => readFileSync(p, 'utf8').trim().split('\n').slice(1).map((l) => l.split(',').map(Number));
const disp = (r) => Math.hypot(r[10] - r[7], r[11] - r[8], r[12] - r[9]);

if (what === 'beam') {
  const rows = csv(a[0]), beam = JSON.parse(readFileSync(a[1], 'utf8'));
  // Deflection of the ring centres: mean over each ring's vertices, by w0 (x along the beam).
  const byX = new Map();
  for (const r of rows) { const k = r[3].toFixed(4); const v = byX.get(k) || [0, 0]; v[0] += Math.hypot(r[10] - r[7], r[12] - r[9]); v[1]++; byX.set(k, v); }
  const xs = [...byX.keys()].map(Number).sort((p, q) => p - q);
  const d = (x) => { const v = byX.get(x.toFixed(4)); return v[0] / v[1]; };
  const tip = d(1), u1 = beam.u[beam.u.length - 1];
  let worst = 0;
  for (const x of xs) {
    const i = Math.round(x * 20);
    if (Math.abs(i / 20 - x) > 1e-6) continue;
    worst = Math.max(worst, Math.abs(d(x) / tip - beam.u[i] / u1));
  }
  if (!(tip > 0)) fail('the beam did not bend');
  if (worst > 0.01) fail(`beam profile differs from the analytic cantilever by ${(worst * 100).toFixed(2)} % of the tip deflection`);
  ok(`beam profile within ${(worst * 100).toFixed(3)} % of the analytic cantilever (tip ${tip.toExponential(3)} m)`);
} else if (what === 'fork') {
  // Mean displacement of the trunk's ring at x = 0.5 and of the child's base ring (x = 0).
  const rows = csv(a[0]);
  const mean = (sel) => { const m = [0, 0, 0]; let n = 0; for (const r of rows) if (sel(r)) { for (let k = 0; k < 3; k++) m[k] += r[10 + k] - r[7 + k]; n++; } return [m.map((v) => v / n), n]; };
  const [trunk, nt] = mean((r) => r[2] === 0 && Math.abs(r[3] - 0.5) < 1e-6), [child, nc] = mean((r) => r[2] === 1 && Math.abs(r[4]) < 1e-6);
  const tipRows = rows.filter((r) => r[2] === 1 && Math.abs(r[4] - 1) < 1e-6);
  const gap = Math.hypot(trunk[0] - child[0], trunk[1] - child[1], trunk[2] - child[2]), move = Math.hypot(...trunk);
  const tip = Math.max(...tipRows.map(disp));
  if (!nt || !nc || !(move > 1e-4)) fail(`fork did not sway (trunk ring ${nt}, child ring ${nc}, move ${move})`);
  if (gap > 1e-3 * move + 1e-6) fail(`child's base ring moved ${gap.toExponential(2)} m apart from the trunk at the attachment (trunk moved ${move.toExponential(2)} m)`);
  if (!(tip > move)) fail(`the child's tip (${tip}) moves no more than its base (${move})`);
  ok(`child's base follows the trunk at the attachment to ${gap.toExponential(2)} m (trunk moved ${move.toExponential(2)} m, child tip ${tip.toExponential(2)} m)`);
} else if (what === 'linear') {
  const A = csv(a[0]), B = csv(a[1]), k = Number(a[2]);
  const ta = Math.max(...A.map(disp)), tb = Math.max(...B.map(disp));
  if (Math.abs(tb / ta - k) > 0.01 * k) fail(`deflection ratio ${(tb / ta).toFixed(4)}, expected ${k}`);
  ok(`deflection ratio ${(tb / ta).toFixed(4)} (expected ${k})`);
} else if (what === 'wind') {
  const A = csv(a[0]), B = csv(a[1]), h = Number(a[2]), frac = Number(a[3]);
  let worst = 0;
  for (let i = 0; i < A.length; i++) worst = Math.max(worst, Math.hypot(B[i][10] - A[i][10], B[i][11] - A[i][11], B[i][12] - A[i][12]));
  if (!(worst <= frac * h)) fail(`vertices moved ${worst.toFixed(4)} m between the dumps, more than ${frac} x ${h} m`);
  ok(`largest move ${worst.toFixed(4)} m <= ${(frac * h).toFixed(4)} m`);
} else if (what === 'moves') {
  const A = csv(a[0]), h = Number(a[1]), frac = Number(a[2]);
  const worst = Math.max(...A.map(disp));
  if (!(worst >= frac * h)) fail(`the wind moved no vertex by ${frac} x ${h} m (largest ${worst})`);
  ok(`wind moves vertices up to ${worst.toFixed(4)} m`);
} else if (what === 'bbox') {
  const img = readPng(a[0]), m = mask(img), v = JSON.parse(readFileSync(a[1], 'utf8')), tol = Number(a[2]);
  let x0 = 1e9, x1 = -1, y0 = 1e9, y1 = -1;
  for (let y = 0; y < img.height; y++) for (let x = 0; x < img.width; x++) if (m[y * img.width + x]) { x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y); }
  // Project the 8 corners with the viewer's camera (look-at, vertical fov, square pixels).
  const [ex, ey, ez] = v.eye, [tx, ty, tz] = v.target;
  let f = [tx - ex, ty - ey, tz - ez]; const fl = Math.hypot(...f); f = f.map((c) => c / fl);
  let s = [f[1] * 0 - f[2] * 1, f[2] * 0 - f[0] * 0, f[0] * 1 - f[1] * 0]; const sl = Math.hypot(...s); s = s.map((c) => c / sl);
  const u = [s[1] * f[2] - s[2] * f[1], s[2] * f[0] - s[0] * f[2], s[0] * f[1] - s[1] * f[0]];
  const t = 1 / Math.tan((v.fovy_deg * Math.PI) / 360), aspect = v.width / v.height;
  const b = v.trees[0];
  let px0 = 1e9, px1 = -1e9, py0 = 1e9, py1 = -1e9;
  for (let c = 0; c < 8; c++) {
    const p = [c & 1 ? b.bounds_max[0] : b.bounds_min[0], c & 2 ? b.bounds_max[1] : b.bounds_min[1], c & 4 ? b.bounds_max[2] : b.bounds_min[2]];
    const d = [p[0] - ex, p[1] - ey, p[2] - ez];
    const z = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
    const sx = ((d[0] * s[0] + d[1] * s[1] + d[2] * s[2]) * t) / aspect / z, sy = ((d[0] * u[0] + d[1] * u[1] + d[2] * u[2]) * t) / z;
    const X = ((sx + 1) / 2) * v.width, Y = ((1 - sy) / 2) * v.height;
    px0 = Math.min(px0, X); px1 = Math.max(px1, X); py0 = Math.min(py0, Y); py1 = Math.max(py1, Y);
  }
  const w = px1 - px0, h = py1 - py0;
  // Outside the box by at most tol of its size (a pixel of rasterisation); spanning at least
  // min_w of its width (cut-out leaf cards are wider than their leaves) and min_h of its height.
  const [minW, minH] = [Number(a[3]), Number(a[4])];
  const off = Math.max((px0 - x0) / w, (x1 + 1 - px1) / w, (py0 - y0) / h, (y1 + 1 - py1) / h);
  const cw = (x1 + 1 - x0) / w, ch = (y1 + 1 - y0) / h;
  if (x1 < 0) fail('nothing rendered');
  const msg = `silhouette [${x0},${x1}]x[${y0},${y1}] vs projected box [${px0.toFixed(1)},${px1.toFixed(1)}]x[${py0.toFixed(1)},${py1.toFixed(1)}]: spans ${(cw * 100).toFixed(1)} % x ${(ch * 100).toFixed(1)} %, outside by ${(Math.max(off, 0) * 100).toFixed(1)} %`;
  if (off > tol || cw < minW || ch < minH) fail(msg);
  ok(msg);
} else if (what === 'iou') {
  const A = readPng(a[0]), B = readPng(a[1]);
  if (A.width !== B.width || A.height !== B.height) fail(`sizes differ: ${A.width}x${A.height} vs ${B.width}x${B.height}`);
  const ma = mask(A), mb = mask(B);
  let i = 0, u = 0;
  for (let k = 0; k < ma.length; k++) { i += ma[k] & mb[k]; u += ma[k] | mb[k]; }
  const iou = u ? i / u : 0;
  if (!(iou >= Number(a[2]))) fail(`silhouette IoU ${iou.toFixed(4)} < ${a[2]} (${i} / ${u} pixels)`);
  ok(`silhouette IoU ${iou.toFixed(4)} (${u} pixels)`);
} else if (what === 'brighter') {
  const A = readPng(a[0]), B = readPng(a[1]);
  const c = (I) => { const k = 4 * ((I.height >> 1) * I.width + (I.width >> 1)); return I.rgba[k] + I.rgba[k + 1] + I.rgba[k + 2]; };
  if (!(c(A) > c(B) + 6)) fail(`centre pixel with translucency ${c(A)} is not brighter than without ${c(B)}`);
  ok(`back-lit leaf: ${c(A)} with translucency, ${c(B)} without (sum of RGB)`);
} else if (what === 'mean_brighter') {
  const A = readPng(a[0]), B = readPng(a[1]), M = mask(readPng(a[2]));
  const m = (I) => { let t = 0, n = 0; for (let i = 0; i < I.width * I.height; i++) if (M[i]) { t += I.rgba[4 * i] + I.rgba[4 * i + 1] + I.rgba[4 * i + 2]; n++; } return t / Math.max(n, 1); };
  if (!(m(A) > m(B) * 1.02)) fail(`mean brightness with translucency ${m(A).toFixed(1)} is not above ${m(B).toFixed(1)} without`);
  ok(`mean brightness ${m(A).toFixed(1)} with translucency, ${m(B).toFixed(1)} without`);
} else if (what === 'hl2') {
  // Expected radiance (docs/leafmaps.md, eq. 3.23): L_D t / pi * max(0, sum_i h_i sqrt(3/(2 pi)) H_i . w),
  // the sun behind the quad (light arrives on the abaxial side, frame T, B, -N), t the diffuse
  // transmission factor x colour, then exposure, Reinhard, gamma 2.2.
  const I = readPng(a[0]), v = JSON.parse(readFileSync(a[1], 'utf8')), tol = Number(a[2]);
  const H = [[-1 / Math.sqrt(6), -1 / Math.SQRT2, 1 / Math.sqrt(3)], [-1 / Math.sqrt(6), 1 / Math.SQRT2, 1 / Math.sqrt(3)], [Math.sqrt(2 / 3), 0, 1 / Math.sqrt(3)]];
  const dec = (h) => -1 + (Math.round(((h + 1) / 4) * 255) / 255) * 4;     // the fixture's 8-bit texels
  const h = [dec(0.5), dec(0.7), dec(1.1)];
  const l = v.sun_dir;
  if (!(l[2] < 0)) fail('the sun must be behind the quad');
  const w = [l[0], l[1], -l[2]];                                          // quad: T = +X, B = +Y, N = +Z
  let rec = 0;
  for (let i = 0; i < 3; i++) rec += h[i] * Math.sqrt(3 / (2 * Math.PI)) * (H[i][0] * w[0] + H[i][1] * w[1] + H[i][2] * w[2]);
  const t = [0.9, 1.0, 0.6].map((c) => 0.6 * c);
  const k = 4 * ((I.height >> 1) * I.width + (I.width >> 1));
  let worst = 0;
  for (let ch = 0; ch < 3; ch++) {
    const want = (v.sun_color[ch] * t[ch] * Math.max(rec, 0) * v.exposure) / Math.PI;
    const c = (I.rgba[k + ch] / 255) ** 2.2, got = c / (1 - c);
    worst = Math.max(worst, Math.abs(got / want - 1));
  }
  if (worst > tol) fail(`HL2 translucency off the reconstruction by ${(worst * 100).toFixed(2)} %`);
  ok(`HL2 translucency within ${(worst * 100).toFixed(2)} % of the reconstruction of the maps`);
} else fail(`unknown check ${what}`);
