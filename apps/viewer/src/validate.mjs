// node validate.mjs FILE.glb: the Khronos glTF validator's report on FILE; prints
// "errors E warnings W" and the messages, exits 1 when there are errors. Used by the tests.
import fs from 'fs';
import validator from 'gltf-validator';

const file = process.argv[2];
const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), { maxIssues: 50 });
const { numErrors, numWarnings, messages } = report.issues;
console.log(`errors ${numErrors} warnings ${numWarnings}`);
for (const m of messages) console.log(`${m.severity === 0 ? 'error' : 'note'} ${m.code} at ${m.pointer}: ${m.message}`);
process.exit(numErrors > 0 ? 1 : 0);
