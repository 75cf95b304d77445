// three.js reads shprobe's `three` export: node three.mjs JOB.json
// JOB: {"cases": [{"name", "text"}], "normals": [x0, y0, z0, x1, ...]}.
// For each case: SphericalHarmonics3.fromArray(coefficients) in a LightProbe, then
// getIrradianceAt and getAt at every normal (flat RGB arrays), and LightProbe.toJSON() of a
// probe holding the same lighting as sh / 2 with intensity 2 (for shprobe's import), and the
// sh that three's ObjectLoader reads back from that JSON.
import { readFileSync } from "node:fs";
import { LightProbe, ObjectLoader, SphericalHarmonics3, Vector3, REVISION } from "three";

const job = JSON.parse(readFileSync(process.argv[2], "utf8"));
const nrm = job.normals;
const out = { revision: REVISION, cases: {} };
for (const c of job.cases) {
  const doc = JSON.parse(c.text);
  const probe = new LightProbe(new SphericalHarmonics3().fromArray(doc.coefficients));
  const n = new Vector3(), t = new Vector3();
  const irr = new Array(nrm.length), rad = new Array(nrm.length);
  for (let i = 0; i < nrm.length; i += 3) {
    n.set(nrm[i], nrm[i + 1], nrm[i + 2]);
    probe.sh.getIrradianceAt(n, t).toArray(irr, i);
    probe.sh.getAt(n, t).toArray(rad, i);
  }
  const half = new LightProbe(probe.sh.clone().scale(0.5), 2.0);
  const json = half.toJSON();
  const loaded = new ObjectLoader().parse(JSON.parse(JSON.stringify(json)));
  out.cases[c.name] = {
    irradiance: irr, radiance: rad, toJSON: json,
    loaded: { type: loaded.type, intensity: loaded.intensity, sh: loaded.sh.toArray() },
  };
}
process.stdout.write(JSON.stringify(out));
