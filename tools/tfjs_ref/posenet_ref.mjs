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
import os from 'node:os';
import path from 'node:path';
import process from 'node:process';
import { performance } from 'node:perf_hooks';

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

function fail(message) {
  process.stderr.write(`posenet_ref: ${message}\n`);
  process.exit(1);
}

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

// TF.js 4.22 turns the multithreaded wasm build off under Node (tfjs issue 3830): its
// Emscripten pthread workers are created from blob: URLs, which Node's Worker cannot load.
// This shim (specific to the pinned 4.22.0 bundle) records the text of the Blobs the backend
// creates, serves the worker script from a temporary file instead of a blob: URL, and gives
// the worker the globals that the bundled factory code refers to. The backend also caps its
// XNNPACK pool at (logical cores / 2), assuming hyper-threading; so that --threads N means N
// threads, os.cpus() is made to report at least 2N entries (only Emscripten reads it).
function enableNodeWasmThreads(tf, threads) {
  const cpus = os.cpus();
  if (cpus.length > 0 && cpus.length < 2 * threads) {
    os.cpus = () => Array.from({ length: 2 * threads }, (_, i) => cpus[i % cpus.length]);
  }
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'posenet_ref-'));
  process.on('exit', () => fs.rmSync(dir, { recursive: true, force: true }));
  const factoryFile = path.join(dir, 'factory.cjs');
  const NodeBlob = globalThis.Blob;
  class RecordingBlob extends NodeBlob {
    constructor(parts, options) {
      super(parts, options);
      this.recordedText = parts.every((p) => typeof p === 'string') ? parts.join('') : null;
      if (this.recordedText?.startsWith('var WasmBackendModuleThreadedSimd')) {
        fs.writeFileSync(factoryFile, this.recordedText);
      }
    }
  }
  globalThis.Blob = RecordingBlob;
  const createObjectURL = URL.createObjectURL;
  let workers = 0;
  URL.createObjectURL = (blob) => {
    if (!(blob instanceof RecordingBlob) || blob.recordedText === null) return createObjectURL(blob);
    const prelude = [
      `globalThis.require$$0 = require('fs');`,
      `globalThis.require$$1 = require('path');`,
      `globalThis.require$$3 = require('perf_hooks');`,
      `globalThis.require$$4 = require('os');`,
      `globalThis.commonjsGlobal = globalThis;`,
      `URL.createObjectURL = () => ${JSON.stringify(factoryFile)};`,
      `URL.revokeObjectURL = () => {};`,
    ].join('\n');
    const file = path.join(dir, `worker${workers++}.cjs`);
    fs.writeFileSync(file, `${prelude}\n${blob.recordedText}`);
    return file;
  };
  tf.env().set('WASM_HAS_MULTITHREAD_SUPPORT', true);
}

function readJson(file) {
  let text;
  try {
    text = fs.readFileSync(file, 'utf8');
  } catch (e) {
    fail(`cannot read model ${file}: ${e.message} (run tools/fetch_models.sh)`);
  }
  try {
    return JSON.parse(text);
  } catch (e) {
    fail(`model ${file} is not valid JSON: ${e.message}`);
  }
  return null;
}

// A TF.js IOHandler that reads the graph JSON and its weight shards from disk. The
// Placeholder's declared height/width are relaxed to -1 so any input size is accepted.
function diskModelHandler(modelPath) {
  const json = readJson(modelPath);
  if (json.format !== 'graph-model' || !json.modelTopology || !json.weightsManifest) {
    fail(`${modelPath}: not a TF.js graph model (format '${json.format}')`);
  }
  const dir = path.dirname(modelPath);
  const weightSpecs = [];
  const shards = [];
  for (const group of json.weightsManifest) {
    weightSpecs.push(...group.weights);
    for (const shard of group.paths) {
      const file = path.join(dir, shard);
      try {
        shards.push(fs.readFileSync(file));
      } catch (e) {
        fail(`cannot read weights ${file}: ${e.message}`);
      }
    }
  }
  const total = shards.reduce((n, b) => n + b.length, 0);
  const weightData = new Uint8Array(total);
  let at = 0;
  for (const b of shards) {
    weightData.set(b, at);
    at += b.length;
  }

  const relax = (dims) => {
    if (Array.isArray(dims) && dims.length === 4) {
      dims[1].size = '-1';
      dims[2].size = '-1';
    }
  };
  const placeholders = json.modelTopology.node.filter((n) => n.op === 'Placeholder');
  if (placeholders.length !== 1) fail(`${modelPath}: expected one Placeholder, found ${placeholders.length}`);
  relax(placeholders[0].attr?.shape?.shape?.dim);
  for (const input of Object.values(json.signature?.inputs ?? {})) relax(input.tensorShape?.dim);
  for (const output of Object.values(json.signature?.outputs ?? {})) relax(output.tensorShape?.dim);

  const computeNodes = json.modelTopology.node
    .filter((n) => n.op !== 'Const' && n.op !== 'Placeholder')
    .map((n) => n.name);
  const handler = {
    load: async () => ({
      modelTopology: json.modelTopology,
      format: json.format,
      generatedBy: json.generatedBy,
      convertedBy: json.convertedBy,
      signature: json.signature,
      userDefinedMetadata: json.userDefinedMetadata,
      weightSpecs,
      weightData: weightData.buffer,
    }),
  };
  return { handler, inputName: placeholders[0].name, computeNodes };
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

function writeF32(file, typed) {
  const out = Buffer.alloc(typed.length * 4);
  for (let i = 0; i < typed.length; ++i) out.writeFloatLE(typed[i], i * 4);
  fs.writeFileSync(file, out);
}

function sanitise(nodeName) {
  return nodeName.replace(/[^A-Za-z0-9._-]/g, '_');
}

function percentile(sortedMs, q) {
  const idx = Math.min(sortedMs.length - 1, Math.max(0, Math.ceil(q * sortedMs.length) - 1));
  return sortedMs[idx];
}

function median(sortedMs) {
  const n = sortedMs.length;
  return n % 2 === 1 ? sortedMs[(n - 1) / 2] : 0.5 * (sortedMs[n / 2 - 1] + sortedMs[n / 2]);
}

const round3 = (x) => Math.round(x * 1000) / 1000;

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
