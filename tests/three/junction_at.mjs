// Prints the close-up "X,Y,Z,R" (glTF frame) of a tree asset's main junction, for
// render_glb.mjs --view close --at: the anchor of the stiffest limb leaving the trunk
// (level 1, parent 0 in the root node's extras.sylva_wind, docs/wind.md), framed by a
// radius of 6 % of the trunk's length. Usage: node tests/three/junction_at.mjs FILE.glb
import { readFileSync } from 'node:fs';

const path = process.argv[2];
const glb = readFileSync(path);
if (glb.readUInt32LE(0) !== 0x46546c67) throw new Error(`${path}: not a glb`);
const gltf = JSON.parse(glb.subarray(20, 20 + glb.readUInt32LE(12)).toString('utf8'));
const wind = gltf.nodes.map(n => n.extras && n.extras.sylva_wind).find(Boolean);
if (!wind) throw new Error(`${path}: no extras.sylva_wind table`);
let best = -1;
for (let b = 0; b < wind.count; b++)
  if (wind.level[b] === 1 && wind.parent[b] === 0 && (best < 0 || wind.stiffness[b] > wind.stiffness[best])) best = b;
if (best < 0) throw new Error(`${path}: no limb leaves the trunk`);
const a = wind.anchor.slice(3 * best, 3 * best + 3), r = Math.max(0.2, 0.06 * wind.length[0]);
console.log([...a, r].map(v => v.toFixed(3)).join(','));
