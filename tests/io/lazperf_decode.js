// Independent LAZ decoder for the tests and benchmarks: the npm package laz-perf (WASM, hobu),
// run under Node. Usage: node lazperf_decode.js <node_modules dir> <in.laz> [<out.records>]
// Decodes every point with laz-perf's LASZip reader, writes the raw point records to
// out.records (when given) and prints "<count> <record length> <decode wall ms> <decode CPU ms>".
const fs = require('fs');
const path = require('path');
const [modules, input, output] = process.argv.slice(2);
const { createLazPerf } = require(path.join(modules, 'laz-perf'));

(async () => {
  const lp = await createLazPerf();
  const file = fs.readFileSync(input);
  const filePtr = lp._malloc(file.length);
  lp.HEAPU8.set(file, filePtr);
  const laszip = new lp.LASZip();
  const t0 = process.hrtime.bigint();
  const c0 = process.cpuUsage();
  laszip.open(filePtr, file.length);
  const count = laszip.getCount();
  const len = laszip.getPointLength();
  const out = output ? Buffer.alloc(count * len) : null;
  const pt = lp._malloc(len);
  for (let i = 0; i < count; ++i) {
    laszip.getPoint(pt);
    if (out) out.set(lp.HEAPU8.subarray(pt, pt + len), i * len);
  }
  const ms = Number(process.hrtime.bigint() - t0) / 1e6;
  const cpu = process.cpuUsage(c0);
  const cpuMs = (cpu.user + cpu.system) / 1e3;
  if (out) fs.writeFileSync(output, out);
  console.log(`${count} ${len} ${ms.toFixed(1)} ${cpuMs.toFixed(1)}`);
  laszip.delete();
  lp._free(pt);
  lp._free(filePtr);
})().catch((e) => { console.error(String(e)); process.exit(1); });
