// Decodes a LAZ file with laz-perf (an independent C++ port of LASzip,
// compiled to WebAssembly) and compares every point record with the records
// of an uncompressed LAS file: node laz_perf_check.mjs FILE.laz FILE.las
// Prints one JSON line; exit status 0 when all records match, 1 otherwise.
// With --time it also reports laz-perf's decode time (bench/laz uses it).
import { createRequire } from 'module';
import { readFileSync } from 'fs';

const require = createRequire(import.meta.url);
const { createLazPerf } = require('laz-perf');

const args = process.argv.slice(2);
const timing = args.includes('--time');
const [lazPath, lasPath] = args.filter((a) => !a.startsWith('--'));
const laz = readFileSync(lazPath);
const las = lasPath ? readFileSync(lasPath) : null;

const LazPerf = await createLazPerf();
const file = LazPerf._malloc(laz.length);
LazPerf.HEAPU8.set(laz, file);
const reader = new LazPerf.LASZip();
const t0 = process.hrtime.bigint();
const c0 = process.cpuUsage();
reader.open(file, laz.length);
const count = reader.getCount();
const length = reader.getPointLength();
const point = LazPerf._malloc(length);
let mismatches = 0;
let first = -1;
let offset = 0, recordLength = 0, lasCount = 0;
if (las) {
  const view = new DataView(las.buffer, las.byteOffset, las.byteLength);
  offset = view.getUint32(96, true);
  recordLength = view.getUint16(105, true);
  lasCount = view.getUint32(107, true);
  if (las[25] >= 4 && view.getUint16(94, true) >= 375) {
    const c64 = Number(view.getBigUint64(247, true));
    if (c64) lasCount = c64;
  }
}
for (let i = 0; i < count; i++) {
  reader.getPoint(point);
  if (!las) continue;
  const got = LazPerf.HEAPU8.subarray(point, point + length);
  const want = las.subarray(offset + i * recordLength, offset + (i + 1) * recordLength);
  if (Buffer.compare(Buffer.from(got), want) !== 0) {
    mismatches++;
    if (first < 0) first = i;
  }
}
const seconds = Number(process.hrtime.bigint() - t0) / 1e9;
const cpu = process.cpuUsage(c0);
reader.delete();
LazPerf._free(point);
LazPerf._free(file);
const ok = !las || (mismatches === 0 && count === lasCount && length === recordLength);
const out = { points: count, record_length: length };
if (las) Object.assign(out, { las_points: lasCount, las_record_length: recordLength, mismatches, first_mismatch: first });
if (timing) Object.assign(out, { seconds, cpu_seconds: (cpu.user + cpu.system) / 1e6 });
console.log(JSON.stringify(out));
process.exit(ok ? 0 : 1);
