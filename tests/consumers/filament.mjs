// Filament (the `filament` npm package: the engine compiled to WebAssembly) reads shprobe's
// `cmgen` export: node filament.mjs JOB.json
// JOB: {"cases": [{"name", "text"}], "normals": [x0, y0, z0, ...]}. The 9 RGB rows of sh.txt
// are taken in order as cmgen writes them (the pre-scaled irradiance SH that
// IndirectLight.Builder.irradianceSh takes); Filament's own
// IndirectLight.getColorEstimate(sh, d) evaluates pi * sum_k sh_k * poly_k(-d) (its shader's
// SH reconstruction, clamped at 0) — the irradiance from direction -d — so d = -n gives E(n).
// getDirectionEstimate(sh) is the direction its band 1 says light travels.
import { readFileSync } from "node:fs";
import { createRequire } from "node:module";

const require = createRequire(import.meta.url);
const factory = require("filament/filament.js");
const Filament = await factory();
const job = JSON.parse(readFileSync(process.argv[2], "utf8"));
const nrm = job.normals;
const num = "[-+]?(?:\\d+\\.?\\d*|\\.\\d+)(?:[eE][-+]?\\d+)?";
const row = new RegExp(`^\\s*\\(\\s*(${num})\\s*,\\s*(${num})\\s*,\\s*(${num})\\s*\\)`, "gm");
const out = { cases: {} };
for (const c of job.cases) {
  const sh = new Float32Array(27);
  let k = 0;
  for (const m of c.text.matchAll(row)) { sh.set([+m[1], +m[2], +m[3]], 3 * k); k++; }
  if (k !== 9) throw new Error(`${c.name}: ${k} rows`);
  const irr = [];
  for (let i = 0; i < nrm.length; i += 3) {
    const e = Filament.IndirectLight.getColorEstimate(sh, [-nrm[i], -nrm[i + 1], -nrm[i + 2]]);
    irr.push(...[0, 1, 2].map((j) => (e[3] > 0 ? e[j] * e[3] : 0)));
  }
  out.cases[c.name] = { irradiance: irr,
    direction: Array.from(Filament.IndirectLight.getDirectionEstimate(sh)) };
}
process.stdout.write(JSON.stringify(out));
