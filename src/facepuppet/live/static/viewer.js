// facepuppet live viewer: a small WebGL2 renderer of morph targets, fed by the server's WebSocket.
// Message formats: facepuppet/live/viewer.py; mesh.bin layout: facepuppet/live/mesh.py.
"use strict";

// Test hook: the morph influences actually applied, frame by frame (bounded), and the page's state.
const hook = window.__facepuppet = {
  ready: false, error: null, names: [], applied: [], maxRecords: 5000, neutralSent: 0, pictures: 0,
};

const $ = (id) => document.getElementById(id);
const SKIN = [0.86, 0.72, 0.62];
const RECENT = 60;   // frames whose curves are kept for their picture, which follows the frame's text
const state = {
  mesh: null, gl: null, prog: null, influences: null, pending: null, head: null, lastIndex: -1,
  dropped: 0, arrivals: [], latency: 0, valid: true, curves: null, curvesIndex: -1, size: null, recent: new Map(),
  bars: [], ws: null,
};

function parseMesh(buffer) {
  const u32 = new Uint32Array(buffer, 0, 5);
  const magic = new TextDecoder().decode(new Uint8Array(buffer, 0, 4));
  if (magic !== "FPM1") throw new Error("mesh.bin: bad magic " + magic);
  const [V, M, T, flags] = [u32[1], u32[2], u32[3], u32[4]];
  let at = 20;
  const neutral = new Float32Array(buffer, at, V * 3); at += V * 12;
  const deltas = new Float32Array(buffer, at, M * V * 3); at += M * V * 12;
  const faces = new Uint32Array(buffer, at, T * 3); at += T * 12;
  const colors = (flags & 1) ? new Uint8Array(buffer, at, V * 4) : null;
  // bounding sphere for the camera, and the pivot of head rotations
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let v = 0; v < V; v++) for (let k = 0; k < 3; k++) {
    const x = neutral[3 * v + k]; if (x < lo[k]) lo[k] = x; if (x > hi[k]) hi[k] = x;
  }
  const center = [0, 1, 2].map((k) => (lo[k] + hi[k]) / 2);
  const radius = 0.5 * Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) || 1;
  return { V, M, T, neutral, deltas, faces, colors, center, radius,
           positions: new Float32Array(V * 3), normals: new Float32Array(V * 3) };
}

const VERTEX = `#version 300 es
in vec3 position; in vec3 normal; in vec4 color;
uniform mat4 projection, view, model;
out vec3 vNormal; out vec4 vColor; out vec3 vEye;
void main() {
  vec4 world = model * vec4(position, 1.0);
  vEye = (view * world).xyz;
  vNormal = mat3(view) * mat3(model) * normal;
  vColor = color;
  gl_Position = projection * view * world;
  gl_PointSize = 2.0;
}`;
const FRAGMENT = `#version 300 es
precision highp float;
in vec3 vNormal; in vec4 vColor; in vec3 vEye;
out vec4 outColor;
void main() {
  vec3 n = normalize(vNormal);
  if (!gl_FrontFacing) n = -n;
  vec3 l = normalize(vec3(0.4, 0.6, 1.0));
  vec3 e = normalize(-vEye);
  float diffuse = max(dot(n, l), 0.0);
  float rim = pow(1.0 - max(dot(n, e), 0.0), 3.0);
  float spec = pow(max(dot(reflect(-l, n), e), 0.0), 24.0);
  vec3 c = vColor.rgb * (0.28 + 0.72 * diffuse) + 0.08 * spec + 0.12 * rim;
  outColor = vec4(pow(c, vec3(1.0 / 1.1)), 1.0);
}`;

function compile(gl, type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source); gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}

function setupGL(mesh) {
  const gl = $("view").getContext("webgl2", { antialias: true, preserveDrawingBuffer: true });
  if (!gl) throw new Error("WebGL2 is not available in this browser");
  const prog = gl.createProgram();
  gl.attachShader(prog, compile(gl, gl.VERTEX_SHADER, VERTEX));
  gl.attachShader(prog, compile(gl, gl.FRAGMENT_SHADER, FRAGMENT));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  gl.useProgram(prog);
  const vao = gl.createVertexArray(); gl.bindVertexArray(vao);
  const buffer = (loc, data, size, type, normalized, usage) => {
    const b = gl.createBuffer(); gl.bindBuffer(gl.ARRAY_BUFFER, b); gl.bufferData(gl.ARRAY_BUFFER, data, usage);
    gl.enableVertexAttribArray(loc); gl.vertexAttribPointer(loc, size, type, normalized, 0, 0); return b;
  };
  const posBuf = buffer(gl.getAttribLocation(prog, "position"), mesh.positions, 3, gl.FLOAT, false, gl.DYNAMIC_DRAW);
  const nrmBuf = buffer(gl.getAttribLocation(prog, "normal"), mesh.normals, 3, gl.FLOAT, false, gl.DYNAMIC_DRAW);
  const colorLoc = gl.getAttribLocation(prog, "color");
  if (mesh.colors) buffer(colorLoc, mesh.colors, 4, gl.UNSIGNED_BYTE, true, gl.STATIC_DRAW);
  else gl.vertexAttrib4f(colorLoc, SKIN[0], SKIN[1], SKIN[2], 1);
  if (mesh.T) {
    const ib = gl.createBuffer(); gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, mesh.faces, gl.STATIC_DRAW);
  }
  gl.enable(gl.DEPTH_TEST);
  const uniforms = {};
  for (const u of ["projection", "view", "model"]) uniforms[u] = gl.getUniformLocation(prog, u);
  Object.assign(state, { gl, prog, posBuf, nrmBuf, uniforms });
}

// Morph: positions = neutral + sum_m w_m * delta_m (the paper's blend of key-models), then smooth normals.
function morph(mesh, w) {
  const p = mesh.positions, n3 = mesh.V * 3;
  p.set(mesh.neutral);
  for (let m = 0; m < mesh.M; m++) {
    const wm = w[m];
    if (wm === 0) continue;
    const d = mesh.deltas.subarray(m * n3, (m + 1) * n3);
    for (let k = 0; k < n3; k++) p[k] += wm * d[k];
  }
  const n = mesh.normals; n.fill(0);
  const f = mesh.faces;
  for (let t = 0; t < f.length; t += 3) {
    const a = 3 * f[t], b = 3 * f[t + 1], c = 3 * f[t + 2];
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    for (const i of [a, b, c]) { n[i] += nx; n[i + 1] += ny; n[i + 2] += nz; }
  }
  if (!f.length) for (let k = 2; k < n3; k += 3) n[k] = 1;
}

function perspective(fovy, aspect, near, far) {
  const f = 1 / Math.tan(fovy / 2), r = 1 / (near - far);
  return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * r, -1, 0, 0, 2 * far * near * r, 0]);
}

// The character's frame: y up, the face looking along +z; the camera looks at it from +z.
function viewMatrix(center, distance) {
  return new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0,
                           -center[0], -center[1], -center[2] - distance, 1]);
}

// model = T(c) R T(-c): the head rotation R (row by row, 9 numbers) about the mesh's centre c.
function modelMatrix(center, h) {
  const R = h || [1, 0, 0, 0, 1, 0, 0, 0, 1];
  const m = new Float32Array(16);
  for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) m[c * 4 + r] = R[3 * r + c];
  for (let r = 0; r < 3; r++) {
    m[12 + r] = center[r] - (R[3 * r] * center[0] + R[3 * r + 1] * center[1] + R[3 * r + 2] * center[2]);
  }
  m[15] = 1;
  return m;
}

function draw() {
  const { gl, mesh } = state;
  const canvas = gl.canvas;
  gl.viewport(0, 0, canvas.width, canvas.height);
  gl.clearColor(0.11, 0.12, 0.14, 1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.bindBuffer(gl.ARRAY_BUFFER, state.posBuf); gl.bufferSubData(gl.ARRAY_BUFFER, 0, mesh.positions);
  gl.bindBuffer(gl.ARRAY_BUFFER, state.nrmBuf); gl.bufferSubData(gl.ARRAY_BUFFER, 0, mesh.normals);
  const fov = 30 * Math.PI / 180, distance = 1.15 * mesh.radius / Math.sin(fov / 2);
  gl.uniformMatrix4fv(state.uniforms.projection, false,
                      perspective(fov, canvas.width / canvas.height, distance / 20, distance * 4));
  gl.uniformMatrix4fv(state.uniforms.view, false, viewMatrix(mesh.center, distance));
  gl.uniformMatrix4fv(state.uniforms.model, false, modelMatrix(mesh.center, state.head));
  if (mesh.T) gl.drawElements(gl.TRIANGLES, mesh.T * 3, gl.UNSIGNED_INT, 0);
  else gl.drawArrays(gl.POINTS, 0, mesh.V);
}

function makeBars(names) {
  const box = $("bars");
  state.bars = names.map((name) => {
    const row = document.createElement("div"); row.className = "bar";
    const label = document.createElement("span"); label.className = "name"; label.textContent = name; label.title = name;
    const track = document.createElement("span"); track.className = "track";
    const fill = document.createElement("span"); fill.className = "fill"; track.appendChild(fill);
    const value = document.createElement("span"); value.className = "value";
    row.append(label, track, value); box.appendChild(row);
    return { fill, value };
  });
}

function apply(msg) {
  const w = state.influences;
  const n = Math.min(w.length, msg.w.length);
  w.fill(0);
  for (let m = 0; m < n; m++) w[m] = msg.w[m];
  state.head = msg.h;
  morph(state.mesh, w);
  draw();
  hook.applied.push({ i: msg.i, w: Array.from(w), h: msg.h });
  if (hook.applied.length > hook.maxRecords) hook.applied.splice(0, hook.applied.length - hook.maxRecords);
  hook.lastApplied = msg.i;
  state.bars.forEach((b, m) => {
    const x = w[m];
    b.fill.style.width = Math.max(0, Math.min(1, x)) * 100 + "%";
    b.value.textContent = x.toFixed(2);
  });
}

function status() {
  const now = performance.now();
  while (state.arrivals.length && state.arrivals[0] < now - 1000) state.arrivals.shift();
  $("status").textContent = `frame ${state.lastIndex}  ${state.arrivals.length} fps  latency ${state.latency.toFixed(1)} ms  ` +
    `${state.valid ? "face found" : "face lost"}  skipped ${state.dropped}`;
}

function tick() {
  if (state.pending) { const msg = state.pending; state.pending = null; apply(msg); }
  requestAnimationFrame(tick);
}

function drawPicture(bitmap, index) {
  const canvas = $("picture"), ctx = canvas.getContext("2d");
  if (canvas.width !== bitmap.width || canvas.height !== bitmap.height) {
    canvas.width = bitmap.width; canvas.height = bitmap.height;
  }
  ctx.drawImage(bitmap, 0, 0);
  hook.pictures += 1;
  // the picture follows its frame's text: draw the curves of the picture's own frame, kept by index
  const own = state.recent.get(index);
  if (!$("show-curves").checked || !own || !own.c || !own.size) return;
  const s = bitmap.width / own.size[0];
  ctx.strokeStyle = "#40e0a0"; ctx.lineWidth = 2;
  for (const c of own.c) {
    ctx.beginPath(); ctx.moveTo(c[0][0] * s, c[0][1] * s);
    ctx.bezierCurveTo(c[1][0] * s, c[1][1] * s, c[2][0] * s, c[2][1] * s, c[3][0] * s, c[3][1] * s);
    ctx.stroke();
  }
}

function onMessage(event) {
  if (typeof event.data === "string") {
    const msg = JSON.parse(event.data);
    if (msg.type !== "frame") return;
    if (state.lastIndex >= 0 && msg.i > state.lastIndex + 1) state.dropped += msg.i - state.lastIndex - 1;
    state.lastIndex = msg.i; state.latency = msg.lat; state.valid = msg.v;
    state.curves = msg.c; state.curvesIndex = msg.i; state.size = msg.size;
    state.recent.set(msg.i, { c: msg.c, size: msg.size });
    for (const k of state.recent.keys()) if (k < msg.i - RECENT) state.recent.delete(k);
    state.arrivals.push(performance.now());
    state.pending = msg;
    status();
  } else {
    const index = new DataView(event.data).getUint32(0, true);
    createImageBitmap(new Blob([event.data.slice(4)], { type: "image/jpeg" }))
      .then((bitmap) => drawPicture(bitmap, index)).catch(() => {});
  }
}

function connect() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = "arraybuffer";
  ws.onopen = () => {
    hook.connected = true;
    ws.send(JSON.stringify({ type: "picture", on: $("show-picture").checked }));
  };
  ws.onmessage = onMessage;
  ws.onclose = () => { hook.connected = false; $("status").textContent = "disconnected, retrying..."; setTimeout(connect, 1000); };
  state.ws = ws;
}

async function main() {
  try {
    const rig = await (await fetch("/rig.json")).json();
    const mesh = parseMesh(await (await fetch("/mesh.bin")).arrayBuffer());
    $("title").textContent = rig.name;
    hook.names = rig.names;
    state.mesh = mesh;
    state.influences = new Float32Array(mesh.M);
    setupGL(mesh);
    morph(mesh, state.influences);
    draw();
    makeBars(rig.names);
    $("neutral").onclick = () => {
      if (state.ws && state.ws.readyState === WebSocket.OPEN) {
        state.ws.send(JSON.stringify({ type: "neutral" })); hook.neutralSent += 1;
      }
    };
    $("show-picture").onchange = (e) => {
      $("camera").classList.toggle("hidden", !e.target.checked);
      if (state.ws && state.ws.readyState === WebSocket.OPEN) {
        state.ws.send(JSON.stringify({ type: "picture", on: e.target.checked }));
      }
    };
    connect();
    requestAnimationFrame(tick);
    hook.ready = true;
  } catch (e) {
    hook.error = String(e && e.stack || e);
    $("status").textContent = "error: " + e;
  }
}

main();
