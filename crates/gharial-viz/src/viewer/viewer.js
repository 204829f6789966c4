// gharial trajectory viewer: draws the scene embedded in the page (element #scene, JSON)
// on a 2D canvas with flat-shaded triangles sorted back to front. No network access.
// URL hash: `#t=1.5` shows time 1.5 s paused, `#play` starts playing.
"use strict";

const errors = [];
function recordError(msg) {
  errors.push(String(msg));
  document.body.dataset.errors = String(errors.length);
  document.getElementById("errors").textContent = errors.join("\n");
}
window.addEventListener("error", (e) => recordError(e.message));
window.addEventListener("unhandledrejection", (e) => recordError(e.reason));
const consoleError = console.error.bind(console);
console.error = (...args) => { recordError(args.join(" ")); consoleError(...args); };

const scene = JSON.parse(document.getElementById("scene").textContent);
const frames = scene.frames;
const duration = (frames - 1) * scene.dt;

// ---- Meshes of the primitive shapes, in their local frames. ----
function boxMesh(s) {
  const [a, b, c] = [s[0] / 2, s[1] / 2, s[2] / 2];
  const v = [];
  for (const x of [-a, a]) for (const y of [-b, b]) for (const z of [-c, c]) v.push([x, y, z]);
  const f = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
  const t = [];
  for (const q of f) { t.push([q[0], q[1], q[2]], [q[0], q[2], q[3]]); }
  return { v, t };
}
function cylinderMesh(r, len, n) {
  const v = [[0, 0, -len / 2], [0, 0, len / 2]];
  for (let i = 0; i < n; i++) {
    const a = (2 * Math.PI * i) / n;
    v.push([r * Math.cos(a), r * Math.sin(a), -len / 2], [r * Math.cos(a), r * Math.sin(a), len / 2]);
  }
  const t = [];
  for (let i = 0; i < n; i++) {
    const j = (i + 1) % n;
    const [b0, t0, b1, t1] = [2 + 2 * i, 3 + 2 * i, 2 + 2 * j, 3 + 2 * j];
    t.push([b0, b1, t1], [b0, t1, t0], [0, b1, b0], [1, t0, t1]);
  }
  return { v, t };
}
function sphereMesh(r, cz) {
  const v = [], t = [], rings = 7, seg = 12;
  for (let i = 0; i <= rings; i++) {
    const p = (Math.PI * i) / rings;
    for (let j = 0; j < seg; j++) {
      const a = (2 * Math.PI * j) / seg;
      v.push([r * Math.sin(p) * Math.cos(a), r * Math.sin(p) * Math.sin(a), cz + r * Math.cos(p)]);
    }
  }
  for (let i = 0; i < rings; i++) for (let j = 0; j < seg; j++) {
    const a = i * seg + j, b = i * seg + ((j + 1) % seg), c = a + seg, d = b + seg;
    t.push([a, c, d], [a, d, b]);
  }
  return { v, t };
}
function merge(...meshes) {
  const v = [], t = [];
  for (const m of meshes) {
    const o = v.length;
    v.push(...m.v);
    for (const tri of m.t) t.push([tri[0] + o, tri[1] + o, tri[2] + o]);
  }
  return { v, t };
}
function meshOf(shape) {
  switch (shape.kind) {
    case "box": return boxMesh(shape.size);
    case "cylinder": return cylinderMesh(shape.radius, shape.length, 16);
    case "sphere": return sphereMesh(shape.radius, 0);
    case "capsule": return merge(cylinderMesh(shape.radius, shape.length, 12),
      sphereMesh(shape.radius, -shape.length / 2), sphereMesh(shape.radius, shape.length / 2));
    case "mesh": {
      const v = [], t = [];
      for (let i = 0; i < shape.vertices.length; i += 3) v.push(shape.vertices.slice(i, i + 3));
      for (let i = 0; i < shape.triangles.length; i += 3) t.push(shape.triangles.slice(i, i + 3));
      return { v, t };
    }
    default: throw new Error("unknown shape " + shape.kind);
  }
}
const bodies = scene.bodies.map((b) => ({ mesh: meshOf(b.shape), color: b.color, poses: b.poses }));
const markers = scene.markers.map((m) => ({
  mesh: meshOf(m.shape), color: m.color, poses: [m.pose], alpha: m.alpha,
}));

// ---- Camera: orbit around the scene's centre. ----
const canvas = document.getElementById("view");
const ctx = canvas.getContext("2d");
const cam = { yaw: scene.camera.yaw, pitch: scene.camera.pitch, dist: scene.camera.distance, target: scene.camera.target };
function basis() {
  const [cy, sy, cp, sp] = [Math.cos(cam.yaw), Math.sin(cam.yaw), Math.cos(cam.pitch), Math.sin(cam.pitch)];
  const back = [cp * cy, cp * sy, sp]; // from the target towards the eye
  const right = [-sy, cy, 0];
  const up = [-sp * cy, -sp * sy, cp];
  const eye = cam.target.map((c, i) => c + cam.dist * back[i]);
  return { back, right, up, eye };
}
function project(p, B, w, h) {
  const d = [p[0] - B.eye[0], p[1] - B.eye[1], p[2] - B.eye[2]];
  const x = d[0] * B.right[0] + d[1] * B.right[1] + d[2] * B.right[2];
  const y = d[0] * B.up[0] + d[1] * B.up[1] + d[2] * B.up[2];
  const z = -(d[0] * B.back[0] + d[1] * B.back[1] + d[2] * B.back[2]);
  const f = (0.9 * Math.min(w, h)) / 2 / Math.tan(0.5);
  return [w / 2 + (f * x) / Math.max(z, 1e-3), h / 2 - (f * y) / Math.max(z, 1e-3), z];
}
function apply(pose, v) {
  const R = pose;
  return [R[0] * v[0] + R[1] * v[1] + R[2] * v[2] + R[9],
    R[3] * v[0] + R[4] * v[1] + R[5] * v[2] + R[10],
    R[6] * v[0] + R[7] * v[1] + R[8] * v[2] + R[11]];
}
const light = (() => { const l = [0.4, -0.3, 0.85]; const n = Math.hypot(...l); return l.map((c) => c / n); })();

// ---- Drawing. ----
let time = 0, playing = false, speed = 1, last = null;
function frameAt(t) { return Math.min(frames - 1, Math.max(0, Math.round(t / scene.dt))); }
function draw() {
  const w = canvas.width, h = canvas.height, B = basis();
  ctx.fillStyle = "#f4f5f7";
  ctx.fillRect(0, 0, w, h);
  drawGround(B, w, h);
  const k = frameAt(time);
  const tris = [];
  const collect = (obj, pose, alpha) => {
    const world = obj.mesh.v.map((v) => apply(pose, v));
    const proj = world.map((p) => project(p, B, w, h));
    for (const [a, b, c] of obj.mesh.t) {
      if (proj[a][2] <= 0.01 || proj[b][2] <= 0.01 || proj[c][2] <= 0.01) continue;
      const u = world[b].map((x, i) => x - world[a][i]), v = world[c].map((x, i) => x - world[a][i]);
      const n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
      const nn = Math.hypot(...n) || 1;
      const shade = 0.35 + 0.65 * Math.abs((n[0] * light[0] + n[1] * light[1] + n[2] * light[2]) / nn);
      tris.push({ p: [proj[a], proj[b], proj[c]], z: (proj[a][2] + proj[b][2] + proj[c][2]) / 3, color: obj.color, shade, alpha });
    }
  };
  for (const b of bodies) collect(b, b.poses[k], 1);
  for (const m of markers) collect(m, m.poses[0], m.alpha);
  tris.sort((a, b) => b.z - a.z);
  for (const t of tris) {
    const c = t.color.map((x) => Math.round(255 * Math.min(1, x * t.shade)));
    ctx.fillStyle = `rgba(${c[0]},${c[1]},${c[2]},${t.alpha})`;
    ctx.strokeStyle = ctx.fillStyle;
    ctx.beginPath();
    ctx.moveTo(t.p[0][0], t.p[0][1]);
    ctx.lineTo(t.p[1][0], t.p[1][1]);
    ctx.lineTo(t.p[2][0], t.p[2][1]);
    ctx.closePath();
    ctx.fill();
    ctx.stroke();
  }
  drawArrows(k, B, w, h);
  document.getElementById("time").textContent = `t = ${(k * scene.dt).toFixed(3)} s / ${duration.toFixed(3)} s`;
  document.getElementById("scrub").value = String(k);
  document.body.dataset.frame = String(k);
  document.body.dataset.time = (k * scene.dt).toFixed(6);
}
function drawGround(B, w, h) {
  ctx.strokeStyle = "#d0d3d8";
  ctx.lineWidth = 1;
  const s = scene.ground.half, n = 10, z = scene.ground.z;
  for (let i = -n; i <= n; i++) {
    const c = (s * i) / n;
    for (const [p, q] of [[[c, -s, z], [c, s, z]], [[-s, c, z], [s, c, z]]]) {
      const a = project(p, B, w, h), b = project(q, B, w, h);
      if (a[2] <= 0.01 || b[2] <= 0.01) continue;
      ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke();
    }
  }
}
function drawArrows(k, B, w, h) {
  const arrows = scene.arrows.length ? scene.arrows[k] : [];
  ctx.strokeStyle = "#c62828";
  ctx.lineWidth = 3;
  for (const a of arrows) {
    const p = project(a.from, B, w, h), q = project(a.from.map((x, i) => x + a.vector[i]), B, w, h);
    if (p[2] <= 0.01 || q[2] <= 0.01) continue;
    ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
    const ang = Math.atan2(q[1] - p[1], q[0] - p[0]);
    ctx.beginPath();
    ctx.moveTo(q[0], q[1]);
    ctx.lineTo(q[0] - 9 * Math.cos(ang - 0.4), q[1] - 9 * Math.sin(ang - 0.4));
    ctx.lineTo(q[0] - 9 * Math.cos(ang + 0.4), q[1] - 9 * Math.sin(ang + 0.4));
    ctx.closePath(); ctx.fillStyle = "#c62828"; ctx.fill();
  }
}

// ---- Playback and controls. ----
function tick(now) {
  if (playing) {
    if (last !== null) time += ((now - last) / 1000) * speed;
    if (time >= duration) { time = duration; setPlaying(false); }
    last = now;
    draw();
    requestAnimationFrame(tick);
  }
}
function setPlaying(p) {
  playing = p;
  last = null;
  document.getElementById("play").textContent = p ? "pause" : "play";
  document.body.dataset.playing = String(p);
  if (p) { if (time >= duration) time = 0; requestAnimationFrame(tick); }
}
document.getElementById("play").addEventListener("click", () => setPlaying(!playing));
const scrub = document.getElementById("scrub");
scrub.max = String(frames - 1);
scrub.addEventListener("input", () => { time = Number(scrub.value) * scene.dt; draw(); });
document.getElementById("speed").addEventListener("change", (e) => { speed = Number(e.target.value); });
let drag = null;
canvas.addEventListener("mousedown", (e) => { drag = [e.clientX, e.clientY]; });
window.addEventListener("mouseup", () => { drag = null; });
window.addEventListener("mousemove", (e) => {
  if (!drag) return;
  cam.yaw -= (e.clientX - drag[0]) * 0.01;
  cam.pitch = Math.max(-1.5, Math.min(1.5, cam.pitch + (e.clientY - drag[1]) * 0.01));
  drag = [e.clientX, e.clientY];
  draw();
});
canvas.addEventListener("wheel", (e) => { e.preventDefault(); cam.dist *= Math.exp(e.deltaY * 0.001); draw(); }, { passive: false });
function resize() {
  canvas.width = Math.max(200, window.innerWidth);
  canvas.height = Math.max(150, window.innerHeight - document.getElementById("bar").offsetHeight);
  draw();
}
window.addEventListener("resize", resize);
function fromHash() {
  const h = window.location.hash.slice(1);
  for (const part of h.split("&")) {
    const [key, value] = part.split("=");
    if (key === "t") time = Math.min(duration, Math.max(0, Number(value) || 0));
    if (key === "speed") speed = Number(value) || 1;
  }
  resize();
  if (h.split("&").includes("play")) setPlaying(true);
}
document.body.dataset.errors = "0";
fromHash();
