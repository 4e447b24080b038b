// node tests/glb_same_tree.mjs A.glb B.glb: exit 0 when the two assets are the
// same tree: identical binary chunks and identical JSON except
// asset.extras.source and source_format (the file each was made from).
import fs from 'node:fs';

function parse(path) {
  const b = fs.readFileSync(path);
  if (b.readUInt32LE(0) !== 0x46546c67) throw new Error(`${path}: not a glb`);
  let off = 12, json = null, bin = Buffer.alloc(0);
  while (off < b.length) {
    const len = b.readUInt32LE(off), type = b.readUInt32LE(off + 4);
    const chunk = b.subarray(off + 8, off + 8 + len);
    if (type === 0x4e4f534a) json = JSON.parse(chunk.toString('utf8'));
    else if (type === 0x004e4942) bin = chunk;
    off += 8 + len;
  }
  if (json.asset && json.asset.extras) {
    delete json.asset.extras.source;
    delete json.asset.extras.source_format;
  }
  return { json: JSON.stringify(json), bin };
}
const [a, b] = process.argv.slice(2).map(parse);
if (a.json !== b.json) { console.error('glb JSON differs (beyond the source fields)'); process.exit(1); }
if (Buffer.compare(a.bin, b.bin) !== 0) { console.error('glb binary chunks differ'); process.exit(1); }
