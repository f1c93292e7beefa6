// mocap-box's page (docs/web.md): the live 3D view from the WebSocket stream, the cameras,
// status, calibration and takes, from the box's own endpoints. Plain ES modules; three.js is
// served by the box. Actions send the access token in the X-Mocap-Token header (never a
// cookie), kept in this browser's localStorage once the box accepted it.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

const $ = (id) => document.getElementById(id);
const TOKEN_KEY = "mocap-box-token";

// ------------------------------------------------------------------------------ box API

const box = {
  token: localStorage.getItem(TOKEN_KEY) || "",
  headers() {
    return this.token ? { "X-Mocap-Token": this.token } : {};
  },
  // {status, body (parsed JSON when it is), text}
  async call(method, path) {
    let r;
    try {
      r = await fetch(path, { method, headers: this.headers(), cache: "no-store" });
    } catch (e) {
      return { status: 0, body: null, text: "the box did not answer: " + e.message };
    }
    const text = await r.text();
    let body = null;
    try { body = JSON.parse(text); } catch (e) { /* not JSON */ }
    return { status: r.status, body, text };
  },
  // A failed action's message, with the fix for a missing token.
  why(r) {
    if (r.status === 401) {
      return "this needs the box's access token: click \u201cEnter token\u201d (`mocap token` on the box prints it)";
    }
    if (r.status === 429) return "too many wrong tokens from this computer: wait a minute";
    return (r.body && r.body.error) || r.text || "HTTP " + r.status;
  },
};

// Stable, distinct colours by person id (the person list shows the same swatches).
const PALETTE = ["#e6194b", "#3cb44b", "#4363d8", "#f58231", "#911eb4", "#42d4f4",
                 "#f032e6", "#bfef45", "#fabed4", "#469990", "#dcbeff", "#9a6324"];
const colourOf = (id) => PALETTE[((id % PALETTE.length) + PALETTE.length) % PALETTE.length];

// ------------------------------------------------------------------------------ 3D view

const view = {
  scene: new THREE.Scene(),
  renderer: null,
  camera: null,
  controls: null,
  persons: new Map(),  // id -> {group, joints: [Mesh], bones: [Mesh], label: div, seen}
  bones: [],           // [[a, b]] joint index pairs of the calibration's topology
  skeletons: {},       // topology name -> its bones (/scene): a frame draws its own topology's
  frustums: new THREE.Group(),
};

function initView() {
  const el = $("view");
  view.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  view.renderer.setPixelRatio(window.devicePixelRatio || 1);
  el.appendChild(view.renderer.domElement);
  view.scene.background = new THREE.Color("#101318");
  view.camera = new THREE.PerspectiveCamera(50, 1, 0.05, 200);
  view.camera.up.set(0, 0, 1);  // the calibration's world is z-up
  view.camera.position.set(5.5, -6.5, 4.2);
  view.controls = new OrbitControls(view.camera, view.renderer.domElement);
  view.controls.target.set(0, 0, 0.9);
  view.controls.update();
  const grid = new THREE.GridHelper(10, 20, 0x5a6472, 0x2c333c);
  grid.rotation.x = Math.PI / 2;  // GridHelper lies in XZ; the floor is XY
  view.scene.add(grid);
  view.scene.add(new THREE.AxesHelper(1));
  view.scene.add(view.frustums);
  new ResizeObserver(resizeView).observe(el);
  resizeView();
}

function resizeView() {
  const el = $("view");
  const w = Math.max(1, el.clientWidth), h = Math.max(1, el.clientHeight);
  view.renderer.setSize(w, h, false);
  view.renderer.domElement.style.width = w + "px";
  view.renderer.domElement.style.height = h + "px";
  view.camera.aspect = w / h;
  view.camera.updateProjectionMatrix();
}

// Camera frustums from the calibration: the centre joined to the image corners at 0.4 m.
function showCameras(cameras) {
  view.frustums.clear();
  const mat = new THREE.LineBasicMaterial({ color: 0xb8c2cc });
  for (const c of cameras) {
    const K = c.K, R = c.R, C = new THREE.Vector3(...c.center_m);
    const fx = K[0][0], fy = K[1][1], cx = K[0][2], cy = K[1][2];
    const corner = (u, v) => {  // world point of pixel (u, v) at depth 0.4 m
      const x = (u - cx) / fx * 0.4, y = (v - cy) / fy * 0.4, z = 0.4;
      return new THREE.Vector3(
        R[0][0] * x + R[1][0] * y + R[2][0] * z + C.x,
        R[0][1] * x + R[1][1] * y + R[2][1] * z + C.y,
        R[0][2] * x + R[1][2] * y + R[2][2] * z + C.z);
    };
    const p = [corner(0, 0), corner(c.width_px, 0), corner(c.width_px, c.height_px),
               corner(0, c.height_px)];
    const pts = [];
    for (let i = 0; i < 4; i++) pts.push(C, p[i], p[i], p[(i + 1) % 4]);
    view.frustums.add(new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(pts), mat));
  }
}

const jointGeometry = new THREE.SphereGeometry(0.045, 12, 8);
const footGeometry = new THREE.SphereGeometry(0.028, 10, 6);
// A foot point planted on the floor (the stream's feet: docs/stream-format.md) is drawn white.
const plantedMaterial = new THREE.MeshBasicMaterial({ color: 0xffffff });
// The foot's segments, by index into the stream's feet (l_heel, r_heel, l_toe, r_toe) and the
// ankle joint names: ankle -> heel and heel -> toe, each side.
const FOOT_SEGMENTS = [["l_ankle", 0], ["r_ankle", 1], [0, 2], [1, 3]];
const boneGeometry = new THREE.CylinderGeometry(0.022, 0.022, 1, 8);  // along +y, unit length
const UP = new THREE.Vector3(0, 1, 0);

// The bones of a frame's topology (its "topology" field), else the calibration's.
function bonesOf(msg) {
  return view.skeletons[msg?.topology] || view.bones;
}

function personObject(id, jointCount, boneCount) {
  const material = new THREE.MeshBasicMaterial({ color: colourOf(id) });
  const group = new THREE.Group();
  const joints = [], bones = [];
  for (let j = 0; j < jointCount; j++) {
    const m = new THREE.Mesh(jointGeometry, material);
    joints.push(m);
    group.add(m);
  }
  for (let b = 0; b < boneCount; b++) {
    const m = new THREE.Mesh(boneGeometry, material);
    bones.push(m);
    group.add(m);
  }
  const feet = [], footBones = [];
  for (let k = 0; k < 4; k++) {
    const m = new THREE.Mesh(footGeometry, material);
    m.visible = false;
    feet.push(m);
    group.add(m);
  }
  for (let k = 0; k < FOOT_SEGMENTS.length; k++) {
    const m = new THREE.Mesh(boneGeometry, material);
    m.visible = false;
    footBones.push(m);
    group.add(m);
  }
  const label = document.createElement("div");
  label.textContent = "id " + id;
  label.style.color = colourOf(id);
  $("labels").appendChild(label);
  view.scene.add(group);
  return { group, joints, bones, feet, footBones, label, material, seen: 0 };
}

function dropPerson(id) {
  const p = view.persons.get(id);
  view.scene.remove(p.group);
  p.material.dispose();
  p.label.remove();
  view.persons.delete(id);
}

const tmpA = new THREE.Vector3(), tmpB = new THREE.Vector3(), tmpD = new THREE.Vector3();

const hasPoint = (j) => !!j && j.x !== null && j.y !== null && j.z !== null;

// A cylinder mesh from a to b (points with x, y, z); hidden when either is missing.
function placeBone(m, a, b) {
  if (!m) return;
  if (!hasPoint(a) || !hasPoint(b)) { m.visible = false; return; }
  tmpA.set(a.x, a.y, a.z);
  tmpB.set(b.x, b.y, b.z);
  tmpD.subVectors(tmpB, tmpA);
  const len = tmpD.length();
  m.visible = len > 1e-4;
  if (!m.visible) return;
  m.position.addVectors(tmpA, tmpB).multiplyScalar(0.5);
  m.scale.set(1, len, 1);
  m.quaternion.setFromUnitVectors(UP, tmpD.divideScalar(len));
}

// The person's foot points (white while planted) and the ankle -> heel -> toe segments; none
// when the stream has no feet for them. Counted into the page's stats.
function applyFeet(p, person, count) {
  const feet = person.feet || [];
  const ankle = (name) => person.joints.find((j) => j.name === name);
  feet.forEach((f, k) => {
    const m = p.feet[k];
    if (!m) return;
    m.visible = hasPoint(f);
    if (!m.visible) return;
    m.position.set(f.x, f.y, f.z);
    m.material = f.contact === "planted" ? plantedMaterial : p.material;
    count.points++;
    if (f.contact === "planted") count.planted++;
  });
  for (let k = feet.length; k < p.feet.length; k++) p.feet[k].visible = false;
  FOOT_SEGMENTS.forEach(([a, b], i) => {
    const from = typeof a === "string" ? ankle(a) : feet[a];
    placeBone(p.footBones[i], from, feet[b]);
  });
}

function applyFrame(msg, frameNo) {
  const bones = bonesOf(msg);
  const feetCount = { points: 0, planted: 0 };
  for (const person of msg.persons || []) {
    let p = view.persons.get(person.id);
    if (p && (p.bones.length !== bones.length || p.joints.length !== person.joints.length)) {
      dropPerson(person.id);  // another topology: rebuilt
      p = null;
    }
    if (!p) {
      p = personObject(person.id, person.joints.length, bones.length);
      view.persons.set(person.id, p);
    }
    p.seen = frameNo;
    const js = person.joints;
    js.forEach((j, i) => {
      const m = p.joints[i];
      if (!m) return;
      m.visible = j.x !== null && j.y !== null && j.z !== null;
      if (m.visible) m.position.set(j.x, j.y, j.z);
    });
    bones.forEach(([a, b], i) => placeBone(p.bones[i], js[a], js[b]));
    applyFeet(p, person, feetCount);
  }
  stats.feet = feetCount;
  for (const [id, p] of view.persons) if (p.seen !== frameNo) dropPerson(id);
}

// Each person's label over its highest joint, in screen pixels.
function placeLabels() {
  const el = $("view"), w = el.clientWidth, h = el.clientHeight;
  for (const p of view.persons.values()) {
    let top = null;
    for (const m of p.joints) if (m.visible && (!top || m.position.z > top.position.z)) top = m;
    if (!top) { p.label.style.display = "none"; continue; }
    tmpA.copy(top.position).setZ(top.position.z + 0.15).project(view.camera);
    p.label.style.display = tmpA.z < 1 ? "" : "none";
    p.label.style.left = ((tmpA.x + 1) / 2 * w) + "px";
    p.label.style.top = ((1 - tmpA.y) / 2 * h) + "px";
  }
}

// ------------------------------------------------------------------------------ stream

// What the page measured (tests and the view's note read it): frames received and drawn, how
// many were skipped to stay on the newest, and the lag of each drawn frame.
const stats = {
  received: 0, rendered: 0, skipped: 0, reconnects: 0,
  lag_ms: [],           // capture (box clock) to drawn (this computer's clock), last 600
  arrival_lag_ms: [],   // message arrival to drawn, last 600: the page's own delay
  persons: [],
  feet: { points: 0, planted: 0 },  // the frame drawn last: foot points drawn, planted ones
};
window.mocapStats = stats;
window.mocapColourOf = colourOf;

let latest = null, latestArrival = 0, drawnFrame = null;

function connectStream() {
  const url = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/stream";
  const protocols = ["mocap.v1"];
  if (box.token) protocols.push("mocap-token." + box.token);  // browsers cannot set headers here
  const ws = new WebSocket(url, protocols);
  ws.onmessage = (ev) => {
    let msg;
    try { msg = JSON.parse(ev.data); } catch (e) { return; }
    stats.received++;
    if (latest && latest !== drawnFrame) stats.skipped++;  // not drawn: the newest wins
    latest = msg;
    latestArrival = performance.now();
  };
  ws.onclose = () => {
    stats.reconnects++;
    setTimeout(connectStream, 1000);
  };
}

function push(list, v) {
  list.push(v);
  if (list.length > 600) list.shift();
}

function frameLoop() {
  requestAnimationFrame(frameLoop);
  if (latest && latest !== drawnFrame) {
    drawnFrame = latest;
    if (latest.type === "skeletons") {
      applyFrame(latest, stats.rendered + 1);
      $("view-note").textContent = "";
    } else {
      for (const id of [...view.persons.keys()]) dropPerson(id);
      $("view-note").textContent = "no calibration yet: the cameras send 2D detections (see Calibration)";
    }
    stats.rendered++;
    push(stats.arrival_lag_ms, performance.now() - latestArrival);
    if (latest.capture_unix_ns) push(stats.lag_ms, Date.now() - latest.capture_unix_ns / 1e6);
    updatePersonList(latest);
  }
  view.controls.update();
  view.renderer.render(view.scene, view.camera);
  placeLabels();
}

let personKey = "";
function updatePersonList(msg) {
  const ids = (msg.persons || []).map((p) => p.id).sort((a, b) => a - b);
  stats.persons = ids;
  const key = ids.join(",");
  if (key === personKey) return;
  personKey = key;
  const ul = $("persons");
  ul.replaceChildren(...ids.map((id) => {
    const li = document.createElement("li");
    li.dataset.personId = id;
    li.dataset.colour = colourOf(id);
    const sw = document.createElement("span");
    sw.className = "swatch";
    sw.style.background = colourOf(id);
    li.append(sw, "person " + id);
    return li;
  }));
}

// ------------------------------------------------------------------------------ status

const fmt = (v, d = 1) => (typeof v === "number" && isFinite(v) ? v.toFixed(d) : "–");

// Where the CNN runs, in words: "CNN on NVIDIA RTX A2000", "CNN on the CPU (software Vulkan,
// llvmpipe)", "no CNN: the simulator gives detections".
function cnnText(g) {
  if (!g) return "CNN ?";
  const device = String(g.device || "");
  if (g.backend === "none") return "no CNN" + (device ? ": " + device.replace(/^not used: /, "") : "");
  const name = device.replace(/^Vulkan on /, "").split(" (")[0];
  if (g.backend === "vulkan") {
    return /llvmpipe|lavapipe|swiftshader/i.test(name)
      ? `CNN on the CPU (software Vulkan, ${name})` : `CNN on ${name || "the GPU"}`;
  }
  return "CNN on the CPU";
}

function showHealth(h) {
  const badge = $("status");
  badge.textContent = h.status;
  badge.className = "badge " + h.status;
  const p = h.pipeline || {};
  $("summary").textContent =
    `${fmt(p.fps)} fps · ${h.persons ?? 0} persons · ${h.source?.kind ?? "?"} · ${cnnText(h.gpu)}`;
  const problems = h.problems || [];
  $("problems").replaceChildren(...(problems.length ? problems : ["none"]).map((t) => {
    const li = document.createElement("li");
    li.textContent = t;
    if (!problems.length) li.className = "muted";
    return li;
  }));
  const rows = [["frames in / out", `${p.frames_in ?? 0} / ${p.frames_out ?? 0}`],
                ["dropped (cnn / assoc)", `${p.dropped?.cnn_queue ?? 0} / ${p.dropped?.assoc_queue ?? 0}`],
                ["errors", p.errors ?? 0]];
  for (const [stage, l] of Object.entries(p.latency || {})) {
    rows.push([stage + " ms (median / p99)", `${fmt(l.median_ms, 2)} / ${fmt(l.p99_ms, 2)}`]);
  }
  const s = h.stream || {};
  rows.push(["stream clients (tcp / ws)", `${s.clients ?? 0} / ${s.websocket_clients ?? 0}`]);
  rows.push(["page: drawn / skipped", `${stats.rendered} / ${stats.skipped}`]);
  // A replay's frames carry the times they were recorded at: capture→drawn means nothing
  // there, the page's own delay (arrival→drawn) does.
  const replay = h.source?.kind === "replay";
  const lag = (replay ? stats.arrival_lag_ms : stats.lag_ms).slice(-60).sort((a, b) => a - b);
  if (lag.length) {
    rows.push([replay ? "page: arrival→drawn ms (replay)" : "page: capture→drawn ms",
               fmt(lag[Math.floor(lag.length / 2)])]);
  }
  $("pipeline").tBodies[0].replaceChildren(...rows.map(([k, v]) => {
    const tr = document.createElement("tr");
    const a = document.createElement("td"), b = document.createElement("td");
    a.textContent = k;
    b.textContent = v;
    b.className = "num";
    tr.append(a, b);
    return tr;
  }));
  showCalibration(h.calibration || {});
  showStage(h);
}

// Several boxes on one stage (docs/scaleout.md): the fusion node's nodes and cameras, or a
// detector node's own publishing. Hidden on a standalone box.
function showStage(h) {
  const panel = $("stage-panel");
  const st = h.stage;
  panel.hidden = !st;
  if (!st) return;
  const row = (cells, cls) => {
    const tr = document.createElement("tr");
    if (cls) tr.className = cls;
    for (const c of cells) {
      const td = document.createElement("td");
      td.textContent = c;
      tr.append(td);
    }
    return tr;
  };
  const rows = [];
  if (st.role === "fusion") {
    const f = st.frames || {};
    $("stage-summary").textContent =
      `fusion · stage ${st.stage} · ${f.released ?? 0} frames, ${f.complete ?? 0} complete, ` +
      `${f.on_deadline ?? 0} on deadline · transport p99 ${fmt(st.transport_ms?.p99, 2)} ms · ` +
      `refused ${(st.refused?.malformed ?? 0) + (st.refused?.unknown_camera ?? 0)}`;
    rows.push(row(["node", "alive", "cameras live", "late / missing", "clock ms"], "head"));
    for (const n of st.nodes || []) {
      const cams = (st.cameras || []).filter((c) => c.node === n.node);
      const live = cams.filter((c) => c.live).length;
      const late = cams.reduce((a, c) => a + c.late, 0);
      const missing = cams.reduce((a, c) => a + c.missing, 0);
      rows.push(row([n.node, n.alive ? "yes" : "LOST", `${live} / ${cams.length}`,
                     `${late} / ${missing}`, fmt(n.clock_corrected_ms || n.clock_offset_ms, 2)],
                    n.alive ? "" : "lost"));
    }
  } else {
    $("stage-summary").textContent =
      `detector ${st.node} · stage ${st.stage} · ${st.frames_published ?? 0} frames published`;
    rows.push(row(["cameras", (st.cameras || []).join(", ")]));
  }
  $("stage").tBodies[0].replaceChildren(...rows);
}

function showCalibration(c) {
  const el = $("calibration");
  const parts = [`<div>state <b>${c.state ?? "?"}</b> · ${c.views ?? 0} views</div>`];
  if (c.progress) {
    const frames = c.progress.frames ?? 0;
    parts.push(`<div>${c.progress.state}: ${frames} frames collected, ${c.progress.attempts ?? 0} attempts</div>`);
    if (c.progress.what_to_do) parts.push(`<div class="muted">${escapeHtml(c.progress.what_to_do)}</div>`);
  }
  const q = c.self_calibration;
  if (q && Array.isArray(q.views)) {
    parts.push(`<div>self-calibration: ${fmt(q.reprojection_median_px, 2)} px median reprojection</div>`);
    parts.push("<table><tr><th>view</th><th>reprojection px (median / p90)</th><th>frames</th></tr>" +
      q.views.map((v) => `<tr><td>${escapeHtml(v.view)}</td><td class="num">${fmt(v.reprojection_median_px, 2)} / ${fmt(v.reprojection_p90_px, 2)}</td><td class="num">${v.frames_with_people ?? ""}</td></tr>`).join("") +
      "</table>");
  }
  if (c.check && c.check.length) {
    parts.push("<table><tr><th>view</th><th>residual px (now / usual)</th><th></th></tr>" +
      c.check.map((v) => `<tr><td>${escapeHtml(v.view)}</td><td class="num">${fmt(v.recent_px)} / ${fmt(v.baseline_px)}</td><td>${v.moved ? "moved: re-solving" : ""}</td></tr>`).join("") +
      "</table>");
  }
  el.innerHTML = parts.join("");
  $("recalibrate").disabled = c.state === "calibrating" || (!!c.progress && c.progress.state !== "done");
}

function escapeHtml(s) {
  return String(s).replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
}

// ------------------------------------------------------------------------------ cameras

const tiles = new Map();  // view index -> {el, img, canvas, caption, loading}

function tileFor(i) {
  let t = tiles.get(i);
  if (t) return t;
  const el = document.createElement("div");
  el.className = "tile";
  el.dataset.view = i;
  el.innerHTML = `<div class="frame"><img alt="camera ${i}"><canvas></canvas></div><div class="caption"></div>`;
  t = { el, img: el.querySelector("img"), canvas: el.querySelector("canvas"),
        caption: el.querySelector(".caption"), loading: false, serial: 0 };
  t.img.onload = () => { t.loading = false; };
  t.img.onerror = () => { t.loading = false; };
  $("cameras").appendChild(el);
  tiles.set(i, t);
  return t;
}

let lastFrames = new Map(), lastCamerasAt = 0;

function showCameras2D(c, scene) {
  const now = performance.now();
  const dt = lastCamerasAt ? (now - lastCamerasAt) / 1000 : 0;
  lastCamerasAt = now;
  const count = Math.max(c.views.length, c.cameras.length, (scene?.cameras || []).length);
  for (let i = 0; i < count; i++) {
    const t = tileFor(i);
    const cam = c.cameras[i] || {};
    const v = c.views.find((x) => x.view === i);
    const state = cam.state || (v ? "streaming" : "waiting");
    t.el.classList.toggle("lost", state === "lost" || state === "failed");
    const frames = cam.frames;
    let fps = "";
    if (frames !== undefined && dt > 0 && lastFrames.has(i)) fps = fmt((frames - lastFrames.get(i)) / dt) + " fps";
    if (frames !== undefined) lastFrames.set(i, frames);
    const name = cam.id || scene?.cameras?.[i]?.name || "view " + i;
    const drops = cam.missing_in_sets !== undefined ? `drops ${cam.missing_in_sets + (cam.late || 0)}` : "";
    t.caption.innerHTML = `<b>${escapeHtml(name)}</b><span class="state-${state}">${state}</span>` +
      `<span>${fps}</span><span>${drops}</span>` +
      (c.thumbnails === "drawn" ? `<span class="muted">simulated view</span>` : "");
    if (v && v.width_px && v.height_px) t.el.querySelector(".frame").style.aspectRatio = `${v.width_px} / ${v.height_px}`;
    if (!t.loading && v) {
      t.loading = true;
      t.img.src = `/cameras/${i}/thumbnail.jpg?n=${++t.serial}`;
    }
    t.v = v;
    drawKeypoints(t.canvas, v, i);
  }
  const skew = c.sync || {};
  $("cameras-panel").querySelector("h2").textContent =
    `Cameras · sync skew median ${fmt(skew.skew_median_ms, 2)} ms, max ${fmt(skew.skew_max_ms, 2)} ms`;
}

function drawKeypoints(canvas, v, i) {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  canvas.width = w;
  canvas.height = h;
  const g = canvas.getContext("2d");
  g.clearRect(0, 0, w, h);
  drawBoard(g, w, h, i);
  if (!v || !v.width_px) return;
  g.fillStyle = "#7fffd4";
  for (const j of v.joints) {
    if (!j || j[2] < 0.2) continue;
    g.beginPath();
    g.arc(j[0] / v.width_px * w, j[1] / v.height_px * h, 3, 0, 2 * Math.PI);
    g.fill();
  }
  drawLimbs(g, w, h, i);
}

// Each person's skeleton of the frame drawn last, seen through camera i (its calibration from
// /scene): the limbs over the camera's keypoints, in the person's colour.
function drawLimbs(g, w, h, i) {
  const cam = scene?.cameras?.[i];
  const msg = drawnFrame;
  if (!cam || !cam.width_px || !msg || msg.type !== "skeletons") return;
  const K = cam.K, R = cam.R, t = cam.t_m;
  const project = (j) => {
    if (!j || j.x === null || j.y === null || j.z === null) return null;
    const c = [0, 1, 2].map((r) => R[r][0] * j.x + R[r][1] * j.y + R[r][2] * j.z + t[r]);
    if (c[2] < 0.05) return null;  // behind the camera
    return [(K[0][0] * c[0] / c[2] + K[0][2]) / cam.width_px * w,
            (K[1][1] * c[1] / c[2] + K[1][2]) / cam.height_px * h];
  };
  g.lineWidth = 2;
  for (const person of msg.persons || []) {
    const pts = person.joints.map(project);
    g.strokeStyle = colourOf(person.id);
    g.beginPath();
    for (const [a, b] of bonesOf(msg)) {
      if (!pts[a] || !pts[b]) continue;
      g.moveTo(pts[a][0], pts[a][1]);
      g.lineTo(pts[b][0], pts[b][1]);
    }
    const feet = (person.feet || []).map(project);
    for (const [a, b] of FOOT_SEGMENTS) {
      const from = typeof a === "string" ? project(person.joints.find((j) => j.name === a)) : feet[a];
      if (!from || !feet[b]) continue;
      g.moveTo(from[0], from[1]);
      g.lineTo(feet[b][0], feet[b][1]);
    }
    g.stroke();
  }
}

// While a board calibration collects: the cells of the image where the board was seen
// (tinted by how often) and the board's corners in the last sampled frame.
function drawBoard(g, w, h, i) {
  const b = board.status;
  if (!b || b.phase !== "collecting") return;
  const cam = (b.cameras || [])[i];
  if (!cam || !cam.width_px) return;
  const grid = cam.grid;
  const cw = w / grid.cols, ch = h / grid.rows;
  for (let r = 0; r < grid.rows; r++) {
    for (let c = 0; c < grid.cols; c++) {
      const n = grid.corners[r * grid.cols + c];
      g.fillStyle = n > 0 ? `rgba(60, 179, 113, ${Math.min(0.45, 0.12 + n / 400)})` : "rgba(224, 80, 80, 0.10)";
      g.fillRect(c * cw + 1, r * ch + 1, cw - 2, ch - 2);
    }
  }
  g.fillStyle = "#ffd24a";
  for (const [x, y] of cam.last.corners_px) {
    g.fillRect(x / cam.width_px * w - 2, y / cam.height_px * h - 2, 4, 4);
  }
}

// ------------------------------------------------------------------------------ takes

// "NDJSON", "JSON", "GLB", "BVH 3" (person 3's).
function fileLabel(f) {
  const person = f.match(/_person(\d+)\.bvh$/);
  return person ? "BVH " + person[1] : f.replace(/^.*\./, "").toUpperCase();
}

function downloadLinks(take) {
  const links = (take.files || []).map((f) =>
    `<a href="#" data-take="${escapeHtml(take.name)}" data-file="${escapeHtml(f)}" title="${escapeHtml(f)}">${escapeHtml(fileLabel(f))}</a>`);
  if (take.exporting) links.push('<span class="muted">exporting…</span>');
  return links.join(" ");
}

function showTakes(t) {
  const rec = t.recording;
  $("record").disabled = !!rec;
  $("stop").disabled = !rec;
  $("takes").tBodies[0].replaceChildren(...(t.takes || []).slice().reverse().map((take) => {
    const tr = document.createElement("tr");
    tr.dataset.take = take.name;
    tr.innerHTML = `<td>${escapeHtml(take.name)}</td><td>${escapeHtml(take.status)}</td>` +
      `<td class="num">${take.frames ?? ""}</td><td>${downloadLinks(take)}</td>`;
    return tr;
  }));
}

// Downloads through fetch so the token header goes along when reading needs it.
async function download(take, file) {
  const r = await fetch(`/takes/${encodeURIComponent(take)}/${encodeURIComponent(file)}`,
                        { headers: box.headers() });
  if (!r.ok) {
    takeMessage(`download of ${file}: ` + box.why({ status: r.status, body: null, text: await r.text() }), true);
    return;
  }
  const url = URL.createObjectURL(await r.blob());
  const a = document.createElement("a");
  a.href = url;
  a.download = file;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}

function takeMessage(text, error) {
  const el = $("take-message");
  el.textContent = text;
  el.className = error ? "error" : "";
}

function initTakes() {
  $("take-form").addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const name = $("take-name").value.trim();
    const r = await box.call("POST", "/takes/start?name=" + encodeURIComponent(name));
    if (r.status === 201) takeMessage(`recording ${r.body.name}`);
    else takeMessage(box.why(r), true);
    refreshTakes();
  });
  $("stop").addEventListener("click", async () => {
    const r = await box.call("POST", "/takes/stop");
    if (r.status === 200) takeMessage(`${r.body.name}: ${r.body.frames} frames, ${r.body.status}`);
    else takeMessage(box.why(r), true);
    refreshTakes();
  });
  $("takes").addEventListener("click", (ev) => {
    const a = ev.target.closest("a[data-file]");
    if (!a) return;
    ev.preventDefault();
    download(a.dataset.take, a.dataset.file);
  });
}

// ------------------------------------------------------------------------------ board calibration

const board = { status: null };
window.mocapBoard = board;  // the last GET /calibration/board, for tests/web/page_test.cjs

function boardMessage(text, error) {
  const el = $("board-message");
  el.textContent = text;
  el.className = error ? "error" : "";
}

function showBoard(b) {
  board.status = b;
  const phase = b.phase || "idle";
  $("board-solve").disabled = phase !== "collecting";
  $("board-save").disabled = phase !== "solved";
  $("board-cancel").disabled = !["collecting", "solving", "solved"].includes(phase);
  $("board-start").disabled = phase === "solving";
  if (phase !== "idle") $("board-panel").open = true;
  const parts = [];
  if (phase !== "idle") {
    // Lines of a fixed height (one line each, the advice three): the progress redraws twice a
    // second, and a height that follows its numbers moved the page under the user's pointer.
    parts.push(`<div class="line"><b>${escapeHtml(phase)}</b> · ${escapeHtml(b.board ?? "")}</div>`);
    parts.push(`<div class="line">${b.samples ?? 0} frame sets with the board · detection ${fmt(b.detect_ms_median)} ms</div>`);
    parts.push(`<div class="muted what">${escapeHtml(b.what_to_do ?? "")}</div>`);
  }
  const result = b.result;
  if (result && Array.isArray(result.cameras)) {
    parts.push(`<div>board reprojection <b>${fmt(result.board_reprojection_px, 2)} px</b> · ${result.board_poses ?? 0} poses` +
               (b.saved_to ? ` · saved to ${escapeHtml(b.saved_to)}` : " · not saved yet") + "</div>");
    parts.push("<table><tr><th>camera</th><th>rms px</th><th>frames</th><th>coverage</th></tr>" +
      result.cameras.map((c) => `<tr><td>${escapeHtml(c.view)}</td><td class="num">${fmt(c.rms_px, 2)}</td>` +
        `<td class="num">${c.frames_posed ?? ""}</td><td class="num">${fmt(100 * (c.coverage ?? 0), 0)} %</td></tr>`).join("") +
      "</table>");
    for (const w of result.warnings || []) parts.push(`<div class="muted">${escapeHtml(w)}</div>`);
  } else if (phase === "collecting" || phase === "solving") {
    parts.push("<table><tr><th>camera</th><th>frames</th><th>coverage</th><th></th></tr>" +
      (b.cameras || []).map((c) => `<tr><td>${escapeHtml(c.view_id)}</td><td class="num">${c.frames_seen}</td>` +
        `<td class="num">${fmt(100 * c.coverage, 0)} %</td><td class="${c.ready ? "ready" : "muted"}">${c.ready ? "ready" : "more"}</td></tr>`).join("") +
      "</table>");
    parts.push("<table><tr><th>pair</th><th>frames seen by both</th></tr>" +
      (b.pairs || []).map((p) => `<tr><td>${escapeHtml(p.a)}–${escapeHtml(p.b)}</td><td class="num">${p.frames}</td></tr>`).join("") +
      "</table>");
  }
  if (b.error) parts.push(`<div class="error">${escapeHtml(b.error)}</div>`);
  $("board-progress").innerHTML = parts.join("");
  for (const [i, t] of tiles) drawKeypoints(t.canvas, t.v, i);
}

async function refreshBoard() {
  const r = await box.call("GET", "/calibration/board");
  if (r.status === 200 && r.body) showBoard(r.body);
}

async function boardAction(path, ok, done) {
  const r = await box.call("POST", path);
  if (r.status === ok) boardMessage(done(r.body));
  else boardMessage(box.why(r), true);
  refreshBoard();
}

function initBoard() {
  $("board-form").addEventListener("submit", (ev) => {
    ev.preventDefault();
    const spec = $("board-spec").value.trim();
    const floor = parseInt($("board-floor").value || "0", 10) || 0;
    const still = $("board-unsynced").checked ? "&still_px=6" : "";
    boardAction(`/calibration/board/start?board=${encodeURIComponent(spec)}&floor_samples=${floor}${still}`, 202,
                (b) => b.what_to_do);
  });
  $("board-solve").addEventListener("click", () =>
    boardAction("/calibration/board/solve", 202, () => "solving in the background: the stream goes on"));
  $("board-save").addEventListener("click", () =>
    boardAction("/calibration/board/save", 200, (b) => `saved to ${b.saved}` +
                (b.backup ? ` (the previous one kept as ${b.backup})` : "") + ": skeletons from the next frame"));
  $("board-cancel").addEventListener("click", () =>
    boardAction("/calibration/board/cancel", 200, () => "discarded: nothing was written"));
}

function initCalibration() {
  $("recalibrate").addEventListener("click", async () => {
    const r = await box.call("POST", "/calibration/recalibrate");
    const el = $("calibration-message");
    el.textContent = r.status === 202 ? r.body.what_to_do : box.why(r);
    el.className = r.status === 202 ? "" : "error";
  });
}

// ------------------------------------------------------------------------------ token

function showLock() {
  $("lock-state").textContent = box.token ? "actions unlocked" : "actions locked";
  $("unlock").textContent = box.token ? "Change token" : "Enter token";
}

function initToken() {
  showLock();
  $("unlock").addEventListener("click", () => {
    $("token-input").value = box.token;
    $("token-message").textContent = "";
    $("token-dialog").showModal();
  });
  $("token-form").addEventListener("submit", async (ev) => {
    if (ev.submitter && ev.submitter.value === "cancel") return;
    ev.preventDefault();
    const old = box.token;
    box.token = $("token-input").value.trim();
    const r = await box.call("POST", "/token/check");
    if (r.status === 200) {
      localStorage.setItem(TOKEN_KEY, box.token);
      $("token-dialog").close();
    } else {
      box.token = old;
      $("token-message").textContent = box.why(r).replace(/: click.*$/, ": not the box's token");
      $("token-message").className = "error";
    }
    showLock();
  });
}

// ------------------------------------------------------------------------------ polling

let scene = null;

async function refreshScene() {
  const r = await box.call("GET", "/scene");
  if (r.status !== 200 || !r.body) return;
  const keyOf = (b) => JSON.stringify(b.cameras) + (b.bones || []).length +
    Object.keys(b.skeletons || {}).join();
  if (scene && keyOf(scene) === keyOf(r.body)) return;
  scene = r.body;
  view.bones = scene.bones || [];
  view.skeletons = scene.skeletons || {};
  for (const id of [...view.persons.keys()]) dropPerson(id);  // rebuilt with the new bones
  showCameras(scene.cameras || []);
}

async function refreshHealth() {
  const r = await box.call("GET", "/health");
  if (r.status === 200 && r.body) {
    showHealth(r.body);
  } else {
    $("status").textContent = r.status === 401 ? "token needed" : "offline";
    $("status").className = "badge offline";
  }
}

async function refreshCameras() {
  const r = await box.call("GET", "/cameras");
  if (r.status === 200 && r.body) showCameras2D(r.body, scene);
}

async function refreshTakes() {
  const r = await box.call("GET", "/takes");
  if (r.status === 200 && r.body) showTakes(r.body);
}

function every(ms, fn) {
  let busy = false;
  const tick = async () => {
    if (busy) return;  // a slow box is not asked again before it answered
    busy = true;
    try { await fn(); } finally { busy = false; }
  };
  tick();
  setInterval(tick, ms);
}

initView();
initTakes();
initCalibration();
initBoard();
initToken();
connectStream();
requestAnimationFrame(frameLoop);
every(1000, refreshHealth);
every(1000, refreshCameras);
every(2000, refreshTakes);
every(5000, refreshScene);
// Often while a board calibration collects (the live corners), seldom otherwise.
every(500, () => {
  const phase = board.status?.phase;
  const active = phase === "collecting" || phase === "solving" || $("board-panel").open;
  if (active || (board.polls = (board.polls || 0) + 1) % 6 === 0) return refreshBoard();
});
