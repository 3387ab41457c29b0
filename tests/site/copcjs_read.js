// Independent COPC reader for the tests and benchmarks: the npm package copc (copc.js, with
// laz-perf's chunk decoder), run under Node. Usage:
//   node copcjs_read.js <node_modules dir> <in.copc.laz> [<out.nodes>]
// Walks the hierarchy from the info VLR's root page through every child page (Copc.create,
// Copc.loadHierarchyPage), decodes every node's chunk (Copc.loadPointDataBuffer) and writes, per
// node, int32 level, x, y, z, int32 point count, then its raw point records to out.nodes (when
// given). Prints one JSON line: the header point count, PDRF, record length, cube, spacing,
// nodes, pages, and nodes and points per level.
const fs = require('fs');
const path = require('path');
const [modules, input, output] = process.argv.slice(2);
const { Copc } = require(path.join(modules, 'copc'));
const { createLazPerf } = require(path.join(modules, 'laz-perf'));

(async () => {
  const lazPerf = await createLazPerf();
  const copc = await Copc.create(input);
  const nodes = {};
  let pages = 0;
  const todo = [copc.info.rootHierarchyPage];
  while (todo.length > 0) {
    const page = await Copc.loadHierarchyPage(input, todo.shift());
    ++pages;
    for (const [key, node] of Object.entries(page.nodes)) {
      if (nodes[key]) throw new Error(`node ${key} listed twice`);
      nodes[key] = node;
    }
    for (const p of Object.values(page.pages)) todo.push(p);
  }
  const keys = Object.keys(nodes).sort((a, b) => {
    const x = a.split('-').map(Number), y = b.split('-').map(Number);
    for (let i = 0; i < 4; ++i) if (x[i] !== y[i]) return x[i] - y[i];
    return 0;
  });
  const len = copc.header.pointDataRecordLength;
  const parts = [];
  const nodesPerLevel = [], pointsPerLevel = [];
  let points = 0;
  for (const key of keys) {
    const node = nodes[key];
    const k = key.split('-').map(Number);
    nodesPerLevel[k[0]] = (nodesPerLevel[k[0]] || 0) + 1;
    pointsPerLevel[k[0]] = (pointsPerLevel[k[0]] || 0) + node.pointCount;
    points += node.pointCount;
    const head = Buffer.alloc(20);
    for (let i = 0; i < 4; ++i) head.writeInt32LE(k[i], 4 * i);
    head.writeInt32LE(node.pointCount, 16);
    if (output) parts.push(head);
    if (node.pointCount > 0) {
      const data = await Copc.loadPointDataBuffer(input, copc.header, node, lazPerf);
      if (data.length !== node.pointCount * len) throw new Error(`node ${key}: ${data.length} bytes decoded`);
      if (output) parts.push(Buffer.from(data.buffer, data.byteOffset, data.length));
    }
  }
  if (output) fs.writeFileSync(output, Buffer.concat(parts));
  const fill = (a) => Array.from({ length: a.length }, (_, i) => a[i] || 0);
  console.log(JSON.stringify({
    header_points: copc.header.pointCount, pdrf: copc.header.pointDataRecordFormat, record_length: len,
    cube: copc.info.cube, spacing: copc.info.spacing, gps_time: copc.info.gpsTimeRange,
    nodes: keys.length, pages, points, nodes_per_level: fill(nodesPerLevel), points_per_level: fill(pointsPerLevel),
  }));
})().catch((e) => { console.error(String(e && e.stack || e)); process.exit(1); });
