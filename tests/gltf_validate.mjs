#!/usr/bin/env node
// Runs the Khronos glTF validator (npm gltf-validator, pinned in
// package-lock.json) on each file given and prints one summary line per file
// plus every info and hint by code. Exit status: 0 when every file has 0
// errors and 0 warnings, 1 otherwise, 2 when the validator is not installed.
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { basename, dirname, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const root = resolve(dirname(fileURLToPath(import.meta.url)), '..');
const require = createRequire(resolve(root, 'package.json'));
let validator;
try {
  validator = require('gltf-validator');
} catch (e) {
  console.error(`gltf_validate: gltf-validator is not installed in ${root}/node_modules; run scripts/install-deps.sh (npm ci)`);
  process.exit(2);
}

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node tests/gltf_validate.mjs FILE.glb...');
  process.exit(2);
}

let failed = false;
for (const file of files) {
  let report;
  try {
    report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
      uri: basename(file),
      maxIssues: 0, // report everything
    });
  } catch (e) {
    console.log(`${file}: validator rejected the file: ${e}`);
    failed = true;
    continue;
  }
  const s = report.issues;
  console.log(`${file}: errors=${s.numErrors} warnings=${s.numWarnings} infos=${s.numInfos} hints=${s.numHints} (validator ${report.validatorVersion})`);
  const severity = ['error', 'warning', 'info', 'hint'];
  const byCode = new Map();
  for (const m of s.messages) {
    const key = `${severity[m.severity]} ${m.code}: ${m.message}`;
    if (!byCode.has(key)) byCode.set(key, []);
    if (m.pointer) byCode.get(key).push(m.pointer);
  }
  for (const [key, where] of [...byCode].sort()) {
    console.log(`  ${key}${where.length > 1 ? ` (x${where.length})` : ''}`);
    if (where.length) console.log(`    at ${where.join(' ')}`);
  }
  if (s.numErrors > 0 || s.numWarnings > 0) failed = true;
}
process.exit(failed ? 1 : 0);
