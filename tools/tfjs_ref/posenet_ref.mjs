#!/usr/bin/env node
// Independent reference for the PoseNet (MobileNetV1, stride 16) TF.js graph model.
//
// Runs models/posenet.json + posenet.bin with TensorFlow.js (cpu or wasm backend) on a raw
// float32 NHWC input and writes the four head outputs as raw float32 NHWC files, so the C++
// runtime can be checked against it. Optionally times the model (--bench) and dumps every
// intermediate node (--dump-layers). Loads everything from disk: no network at run time.
//
//   node tools/tfjs_ref/posenet_ref.mjs --model models/posenet.json --input-f32 FILE --size S
//        --out DIR [--backend cpu|wasm] [--threads N] [--bench N] [--warmup W]
//        [--dump-layers DIR]
//
// FILE: little-endian float32 [1,S,S,3], RGB already normalised to [-1,1] (u8/127.5 - 1).
// Outputs in DIR: heatmap.f32, offsets.f32, displacement_fwd.f32, displacement_bwd.f32.
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
  round3,
  sanitise,
  setProgram,
  writeF32,
} from './tfjs_common.mjs';

setProgram('posenet_ref');

const require = createRequire(import.meta.url);

const USAGE = `usage: node tools/tfjs_ref/posenet_ref.mjs --model models/posenet.json --input-f32 FILE
       --size S --out DIR [--backend cpu|wasm] [--threads N] [--bench N] [--warmup W]
       [--dump-layers DIR]`;

// Output file -> graph node (the model's four heads).
const HEADS = [
  ['heatmap.f32', 'MobilenetV1/heatmap_2/BiasAdd'],
  ['offsets.f32', 'MobilenetV1/offset_2/BiasAdd'],
  ['displacement_fwd.f32', 'MobilenetV1/displacement_fwd_2/BiasAdd'],
  ['displacement_bwd.f32', 'MobilenetV1/displacement_bwd_2/BiasAdd'],
];
const MAX_SIZE_PX = 4096;


function parseArgs(argv) {
  const opts = {
    model: null,
    inputF32: null,
    size: null,
    out: null,
    backend: 'wasm',
    threads: null,
    bench: 0,
    warmup: 3,
    dumpLayers: null,
  };
  const keys = {
    '--model': 'model',
    '--input-f32': 'inputF32',
    '--size': 'size',
    '--out': 'out',
    '--backend': 'backend',
    '--threads': 'threads',
    '--bench': 'bench',
    '--warmup': 'warmup',
    '--dump-layers': 'dumpLayers',
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
    ['--input-f32', 'inputF32'],
    ['--size', 'size'],
    ['--out', 'out'],
  ]) {
    if (opts[key] === null) fail(`missing ${flag}\n${USAGE}`);
  }
  if (opts.backend !== 'cpu' && opts.backend !== 'wasm') {
    fail(`--backend must be cpu or wasm, got '${opts.backend}'`);
  }
  if (opts.size < 17 || opts.size > MAX_SIZE_PX) {
    fail(`--size ${opts.size} out of range: need 17..${MAX_SIZE_PX} (sizes 16k+1 such as 257, 353, 513 match PoseNet's grid)`);
  }
  if (opts.threads !== null) {
    if (opts.threads < 1) fail('--threads must be >= 1');
    if (opts.backend !== 'wasm') fail('--threads only applies to --backend wasm');
  }
  return opts;
}

function readInput(file, sizePx) {
  let bytes;
  try {
    bytes = fs.readFileSync(file);
  } catch (e) {
    fail(`cannot read input ${file}: ${e.message}`);
  }
  const expected = sizePx * sizePx * 3 * 4;
  if (bytes.length !== expected) {
    const pixels = bytes.length / 12;
    const side = Math.sqrt(pixels);
    const hint = Number.isInteger(side) ? ` (looks like --size ${side})` : '';
    fail(
      `${file}: ${bytes.length} bytes, but --size ${sizePx} needs 1x${sizePx}x${sizePx}x3 float32 = ${expected} bytes${hint}`,
    );
  }
  const values = new Float32Array(sizePx * sizePx * 3);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let outOfRange = 0;
  for (let i = 0; i < values.length; ++i) {
    const v = view.getFloat32(i * 4, true);
    if (!Number.isFinite(v)) fail(`${file}: value ${i} is not finite (${v})`);
    if (v < -1.0001 || v > 1.0001) ++outOfRange;
    values[i] = v;
  }
  if (outOfRange > 0) {
    process.stderr.write(
      `posenet_ref: warning: ${outOfRange} input values outside [-1,1]; PoseNet expects u8/127.5 - 1\n`,
    );
  }
  return values;
}

async function main() {
  const opts = parseArgs(process.argv.slice(2));
  const tf = require('@tensorflow/tfjs-core');
  require('@tensorflow/tfjs-backend-cpu');
  const wasm = require('@tensorflow/tfjs-backend-wasm');
  const tfconv = require('@tensorflow/tfjs-converter');

  let simd = false;
  if (opts.backend === 'wasm') {
    simd = await tf.env().getAsync('WASM_HAS_SIMD_SUPPORT');
    if (opts.threads !== null) {
      if (opts.threads > 1) enableNodeWasmThreads(tf, opts.threads);
      wasm.setThreadsCount(opts.threads);
    }
  }
  const ok = await tf.setBackend(opts.backend);
  if (!ok) fail(`backend '${opts.backend}' failed to initialise`);
  await tf.ready();
  let threads = 1;
  if (opts.backend === 'wasm') threads = wasm.getThreadsCount();
  if (opts.threads !== null && threads !== opts.threads) {
    process.stderr.write(`posenet_ref: warning: asked for ${opts.threads} threads, wasm uses ${threads}\n`);
  }

  const { handler, inputName, computeNodes } = diskModelHandler(opts.model);
  const model = await tfconv.loadGraphModel(handler);
  const inputValues = readInput(opts.inputF32, opts.size);
  if ((opts.size - 1) % 16 !== 0) {
    process.stderr.write(
      `posenet_ref: note: size ${opts.size} is not 16k+1; SAME padding becomes asymmetric\n`,
    );
  }
  const input = tf.tensor4d(inputValues, [1, opts.size, opts.size, 3], 'float32');
  const feed = { [inputName]: input };
  const headNodes = HEADS.map(([, node]) => node);

  const runOnce = async () => {
    const outs = model.execute(feed, headNodes);
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
    `posenet_ref: backend=${opts.backend} simd=${simd} threads=${threads} input=[1,${opts.size},${opts.size},3]\n`,
  );
  HEADS.forEach(([file, node], i) => {
    writeF32(path.join(opts.out, file), first.data[i]);
    process.stderr.write(`  ${file}: [${first.shapes[i].join(',')}] <- ${node}\n`);
  });

  if (opts.dumpLayers !== null) {
    fs.mkdirSync(opts.dumpLayers, { recursive: true });
    const outs = model.execute(feed, computeNodes);
    for (let i = 0; i < computeNodes.length; ++i) {
      const file = path.join(opts.dumpLayers, `${sanitise(computeNodes[i])}.f32`);
      writeF32(file, await outs[i].data());
      process.stderr.write(`  layer ${computeNodes[i]}: [${outs[i].shape.join(',')}]\n`);
    }
    tf.dispose(outs);
    process.stderr.write(`posenet_ref: ${computeNodes.length} layer outputs in ${opts.dumpLayers}\n`);
  }

  if (opts.bench > 0) {
    for (let i = 0; i < opts.warmup; ++i) await runOnce();
    const times = [];
    for (let i = 0; i < opts.bench; ++i) {
      const t0 = performance.now();
      await runOnce();
      times.push(performance.now() - t0);
    }
    times.sort((a, b) => a - b);
    const report = {
      backend: opts.backend,
      simd,
      threads,
      size: opts.size,
      runs: opts.bench,
      median_ms: round3(median(times)),
      p90_ms: round3(percentile(times, 0.9)),
      min_ms: round3(times[0]),
    };
    process.stdout.write(`${JSON.stringify(report)}\n`);
  }

  input.dispose();
  model.dispose();
}

main().then(
  () => process.exit(0),
  (e) => fail(e && e.stack ? e.stack : String(e)),
);
