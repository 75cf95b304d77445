// Khronos glTF-Validator on every glTF document of a job: node validate_gltf.mjs JOB.json
// JOB: {"cases": [{"name", "text"}]}; prints {"name": {"numErrors", "numWarnings", "numInfos",
// "messages": [...]}} as JSON.
import { readFileSync } from "node:fs";
import validator from "gltf-validator";

const job = JSON.parse(readFileSync(process.argv[2], "utf8"));
const out = {};
for (const c of job.cases) {
  const report = await validator.validateBytes(new TextEncoder().encode(c.text), {
    uri: `${c.name}.gltf`,
    maxIssues: 100,
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri}`)),
  });
  out[c.name] = { ...report.issues, version: report.validatorVersion };
}
process.stdout.write(JSON.stringify(out));
