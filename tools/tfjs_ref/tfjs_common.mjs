// Helpers shared by the TF.js reference runners (posenet_ref.mjs, movenet_ref.mjs,
// blazepose_ref.mjs): the backend set-up (wasm threads under Node), a disk IOHandler for graph
// models, raw input and float32 output, and timing statistics. Loads everything from disk: no network at run time.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import process from 'node:process';

let program = 'tfjs_ref';

// The name error messages start with.
export function setProgram(name) {
  program = name;
}

export function fail(message) {
  process.stderr.write(`${program}: ${message}\n`);
  process.exit(1);
}

// TF.js 4.22 turns the multithreaded wasm build off under Node (tfjs issue 3830): its
// Emscripten pthread workers are created from blob: URLs, which Node's Worker cannot load.
// This shim (specific to the pinned 4.22.0 bundle) records the text of the Blobs the backend
// creates, serves the worker script from a temporary file instead of a blob: URL, and gives
// the worker the globals that the bundled factory code refers to. The backend also caps its
// XNNPACK pool at (logical cores / 2), assuming hyper-threading; so that --threads N means N
// threads, os.cpus() is made to report at least 2N entries (only Emscripten reads it).
export function enableNodeWasmThreads(tf, threads) {
  const cpus = os.cpus();
  if (cpus.length > 0 && cpus.length < 2 * threads) {
    os.cpus = () => Array.from({ length: 2 * threads }, (_, i) => cpus[i % cpus.length]);
  }
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), `${program}-`));
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
export function diskModelHandler(modelPath) {
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

// The bytes of an input file, which must be `expected` long (`what` names the tensor).
export function readBytes(file, expected, what) {
  let bytes;
  try {
    bytes = fs.readFileSync(file);
  } catch (e) {
    fail(`cannot read input ${file}: ${e.message}`);
  }
  if (bytes.length !== expected) fail(`${file}: ${bytes.length} bytes, ${what} needs ${expected}`);
  return bytes;
}

// `count` little-endian float32 values of an input file, every one finite.
export function readF32(file, count, what) {
  const bytes = readBytes(file, count * 4, what);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const values = new Float32Array(count);
  for (let i = 0; i < count; ++i) {
    values[i] = view.getFloat32(i * 4, true);
    if (!Number.isFinite(values[i])) fail(`${file}: value ${i} is not finite`);
  }
  return values;
}

export function writeF32(file, typed) {
  const out = Buffer.alloc(typed.length * 4);
  for (let i = 0; i < typed.length; ++i) out.writeFloatLE(typed[i], i * 4);
  fs.writeFileSync(file, out);
}

export function sanitise(nodeName) {
  return nodeName.replace(/[^A-Za-z0-9._-]/g, '_');
}

export function percentile(sortedMs, q) {
  const idx = Math.min(sortedMs.length - 1, Math.max(0, Math.ceil(q * sortedMs.length) - 1));
  return sortedMs[idx];
}

export function median(sortedMs) {
  const n = sortedMs.length;
  return n % 2 === 1 ? sortedMs[(n - 1) / 2] : 0.5 * (sortedMs[n / 2 - 1] + sortedMs[n / 2]);
}

export const round3 = (x) => Math.round(x * 1000) / 1000;
