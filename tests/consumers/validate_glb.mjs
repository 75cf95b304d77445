// Khronos glTF-Validator on binary glTF files: node validate_glb.mjs A.glb [B.glb …]
// prints {"A.glb": {"numErrors", "numWarnings", "numInfos", "messages": [...]}} as JSON.
import { readFileSync } from "node:fs";
import { basename } from "node:path";
import validator from "gltf-validator";

const out = {};
for (const path of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(path)), {
    uri: basename(path),
    maxIssues: 100,
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri}`)),
  });
  out[basename(path)] = { ...report.issues, version: report.validatorVersion };
}
process.stdout.write(JSON.stringify(out));
