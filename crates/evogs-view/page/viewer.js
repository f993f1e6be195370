// evogs view: the page. Holds one camera and one time for every pane, asks the server for a
// view of each run whenever they change (at most one request in flight per pane; the newest
// wanted view is asked next), preview resolution while moving, full resolution when still.
'use strict';

const PERIOD_S = 5; // seconds for t to run from 0 to 1 at speed 1
const ORBIT_RAD_PER_PX = 0.006;
const testMode = new URLSearchParams(location.search).get('png') === '1';
const fmt = testMode ? '&fmt=png' : '';

const $ = (id) => document.getElementById(id);
const v3 = {
  sub: (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]],
  add: (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]],
  mul: (a, s) => [a[0] * s, a[1] * s, a[2] * s],
  dot: (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2],
  cross: (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
  len: (a) => Math.hypot(a[0], a[1], a[2]),
  norm: (a) => { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; },
  // Rodrigues: v rotated by `angle` about the unit `axis`.
  rot: (v, axis, angle) => {
    const c = Math.cos(angle), s = Math.sin(angle);
    const k = v3.cross(axis, v), d = v3.dot(axis, v) * (1 - c);
    return [v[0] * c + k[0] * s + axis[0] * d, v[1] * c + k[1] * s + axis[1] * d, v[2] * c + k[2] * s + axis[2] * d];
  },
};

const S = {
  info: null,
  runs: 0,
  base: { w: 400, h: 400 },
  // Camera: rows of R (x right, y down, z forward, OpenCV), centre C, intrinsics K at base size.
  cam: null,
  target: [0, 0, 0],
  up: [0, 0, 1],
  dataset: null, // {split, index} while the view is exactly a dataset camera
  t: 0,
  playing: false,
  speed: 1,
  scale: 1,
  moving: false,
  movingTimer: 0,
  panes: [],
  gt: null,
  versions: [],
  done: [], // completion times of renders, for views/s
  lastMs: [],
  error: '',
};

function fmtNum(x) { return Number.isInteger(x) ? String(x) : x.toPrecision(9).replace(/0+$/, '').replace(/\.$/, ''); }

function rows() { const R = S.cam.R; return [R.slice(0, 3), R.slice(3, 6), R.slice(6, 9)]; }

function setRows(r, d, f) {
  // Gram-Schmidt from forward and right, down = forward × right (right-handed OpenCV axes).
  f = v3.norm(f);
  r = v3.norm(v3.sub(r, v3.mul(f, v3.dot(r, f))));
  d = v3.cross(f, r);
  S.cam.R = [...r, ...d, ...f];
}

function size(preview) {
  let s = S.scale * (preview ? 0.5 : 1);
  return { w: Math.max(1, Math.round(S.base.w * s)), h: Math.max(1, Math.round(S.base.h * s)) };
}

function cameraQuery(sz) {
  if (S.dataset) return `cam=dataset:${S.dataset.split}:${S.dataset.index}&w=${sz.w}&h=${sz.h}`;
  const sx = sz.w / S.base.w, sy = sz.h / S.base.h;
  const K = [S.cam.K[0] * sx, S.cam.K[1] * sy, S.cam.K[2] * sx, S.cam.K[3] * sy];
  return `R=${S.cam.R.map(fmtNum).join(',')}&C=${S.cam.C.map(fmtNum).join(',')}` +
    `&K=${K.map(fmtNum).join(',')}&w=${sz.w}&h=${sz.h}`;
}

// Control points are drawn on the runs that have them (SC-GS's), when the box is ticked.
function controlsQuery(run) {
  return $('controls').checked && S.info.runs[run].control_points != null ? '&controls=1' : '';
}

function renderUrl(run, preview) {
  return `/api/render?run=${run}&${cameraQuery(size(preview))}&t=${fmtNum(S.t)}${controlsQuery(run)}${fmt}`;
}

function makePanes() {
  const main = $('panes');
  main.textContent = '';
  S.panes = [];
  for (let i = 0; i < S.runs; i++) {
    const fig = document.createElement('figure');
    const view = document.createElement('div');
    view.className = 'view';
    view.id = `view-${i}`;
    const img = document.createElement('img');
    img.alt = `run ${i}`;
    img.id = `img-${i}`;
    view.appendChild(img);
    const cap = document.createElement('figcaption');
    fig.append(view, cap);
    main.appendChild(fig);
    attachControls(view);
    S.panes.push({ view, img, cap, shown: '', inflight: null, objectUrl: null });
  }
  const fig = document.createElement('figure');
  fig.id = 'gt-figure';
  fig.hidden = true;
  const gtView = document.createElement('div');
  gtView.className = 'view';
  const gtImg = document.createElement('img');
  gtImg.id = 'img-gt';
  gtImg.alt = 'ground truth';
  gtView.appendChild(gtImg);
  const gtCap = document.createElement('figcaption');
  fig.append(gtView, gtCap);
  main.appendChild(fig);
  S.gt = { fig, view: gtView, img: gtImg, cap: gtCap, shown: '' };
  layout();
}

function layout() {
  const full = size(false);
  for (const p of [...S.panes, S.gt]) {
    p.view.style.width = `${full.w}px`;
    p.view.style.height = `${full.h}px`;
  }
}

function caption(i) {
  const r = S.info.runs[i];
  const psnr = Object.entries(r.psnr).map(([k, v]) => `${k} ${Number(v).toFixed(2)} dB`).join(', ');
  const controls = r.control_points != null ? `, ${r.control_points} control points` : '';
  return `${r.name}: ${r.label}, ${r.gaussians} Gaussians${controls}, iteration ${r.iteration}/${r.iterations}` +
    (r.source === 'checkpoint' ? ' (checkpoint)' : '') +
    (psnr ? `, PSNR ${psnr}` : ', no eval files') + (r.note ? ` — ${r.note}` : '') +
    (r.reload_error ? ` — reload failed: ${r.reload_error}` : '');
}

// A path as one shell word: as it is when it holds only safe characters, else single-quoted.
function shellWord(s) {
  return /^[\w\/.,:+@%=-]+$/.test(s) ? s : `'${s.replace(/'/g, "'\\''")}'`;
}

// The first scale at which a run's images are at least 384 px wide on the page (a 64 × 64 demo
// run is drawn at 6×, rendered at that size, not stretched); full size for larger runs.
function autoScale(width) {
  return [1, 1.5, 2, 4, 6].find((s) => width * s >= 384) || 6;
}

function updateStats() {
  const now = performance.now();
  S.done = S.done.filter((x) => now - x < 2000);
  // The rate over the last 2 s; nothing drawn in them: the view is still, not slow.
  const rate = S.done.length ? `${(S.done.length / 2).toFixed(1)} views/s` : 'idle';
  const ms = S.lastMs.map((m) => (m == null ? '–' : `${m} ms`)).join(' / ');
  const backend = S.info ? S.info.runs.map((r) => r.backend).join(' | ') : '';
  $('stats').textContent = `${rate} · render ${ms} · ${backend}` +
    (S.error ? ` · ${S.error}` : '');
  S.panes.forEach((p, i) => { p.cap.textContent = caption(i); });
  const sz = size(false);
  const show = controlsQuery(0) ? ' --show-controls' : '';
  $('command').textContent = `evogs render --run ${shellWord(S.info.runs[0].path)} --camera camera.json --time ${fmtNum(S.t)}${show} --out view.png` +
    ` (${sz.w}×${sz.h}; "save camera" writes camera.json)`;
}

function wantPreview() { return $('preview').checked && (S.moving || S.playing); }

function pump() {
  if (!S.info) return;
  const preview = wantPreview();
  S.panes.forEach((p, i) => {
    const url = renderUrl(i, preview);
    p.wanted = url;
    if (p.inflight || p.shown === url) return;
    p.inflight = url;
    const started = performance.now();
    fetch(url).then(async (res) => {
      if (res.status === 409) return; // superseded: the newer request is ours too
      if (!res.ok) { S.error = `render: ${res.status} ${(await res.text()).trim()}`; p.shown = url; return; }
      S.lastMs[i] = res.headers.get('X-Render-Ms');
      const blob = await res.blob();
      const obj = URL.createObjectURL(blob);
      await new Promise((ok) => { p.img.onload = ok; p.img.onerror = ok; p.img.src = obj; });
      if (p.objectUrl) URL.revokeObjectURL(p.objectUrl);
      p.objectUrl = obj;
      p.shown = url;
      p.img.dataset.url = url;
      S.error = '';
      S.done.push(performance.now());
      void started;
    }).catch((e) => { S.error = `render: ${e}`; p.shown = url; })
      .finally(() => { p.inflight = null; updateStats(); pump(); });
  });
  const gt = S.gt;
  if (S.dataset) {
    const url = `/api/gt?split=${S.dataset.split}&index=${S.dataset.index}${fmt}`;
    gt.fig.hidden = false;
    gt.cap.textContent = `ground truth: ${S.dataset.split} ${S.dataset.index} (t = ${fmtNum(S.cameraTime)})`;
    if (gt.shown !== url) { gt.shown = url; gt.img.src = url; }
  } else {
    gt.fig.hidden = true;
  }
}

// The view changes; `cameraMoved` false for a change of time only (a dataset camera stays).
function moved(cameraMoved = true) {
  if (cameraMoved) S.dataset = null;
  S.moving = true;
  clearTimeout(S.movingTimer);
  S.movingTimer = setTimeout(() => { S.moving = false; pump(); }, 200);
  pump();
}

function orbit(dx, dy) {
  let [r, d, f] = rows();
  const up = S.up;
  const yaw = -dx * ORBIT_RAD_PER_PX, pitch = dy * ORBIT_RAD_PER_PX;
  let off = v3.sub(S.cam.C, S.target);
  off = v3.rot(off, up, yaw); r = v3.rot(r, up, yaw); d = v3.rot(d, up, yaw); f = v3.rot(f, up, yaw);
  const right = v3.norm(r);
  off = v3.rot(off, right, pitch); d = v3.rot(d, right, pitch); f = v3.rot(f, right, pitch);
  S.cam.C = v3.add(S.target, off);
  setRows(r, d, f);
  moved();
}

function pan(dx, dy) {
  const [r, d, f] = rows();
  const depth = Math.max(1e-3, v3.dot(v3.sub(S.target, S.cam.C), f));
  const k = depth / S.cam.K[0];
  const delta = v3.add(v3.mul(r, -dx * k), v3.mul(d, -dy * k));
  S.cam.C = v3.add(S.cam.C, delta);
  S.target = v3.add(S.target, delta);
  moved();
}

function zoom(factor) {
  S.cam.C = v3.add(S.target, v3.mul(v3.sub(S.cam.C, S.target), factor));
  moved();
}

function attachControls(el) {
  const pointers = new Map();
  let mode = null;
  let last = null;
  el.addEventListener('contextmenu', (e) => e.preventDefault());
  el.addEventListener('pointerdown', (e) => {
    el.setPointerCapture(e.pointerId);
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    mode = pointers.size >= 2 ? 'pinch' : (e.button === 2 || e.shiftKey ? 'pan' : 'orbit');
    last = null;
    el.classList.add('dragging');
    S.moving = true;
  });
  el.addEventListener('pointermove', (e) => {
    if (!pointers.has(e.pointerId)) return;
    const prev = pointers.get(e.pointerId);
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY });
    if (mode === 'pinch' && pointers.size >= 2) {
      const [a, b] = [...pointers.values()];
      const now = { mx: (a.x + b.x) / 2, my: (a.y + b.y) / 2, dist: Math.hypot(a.x - b.x, a.y - b.y) };
      if (last) {
        pan(now.mx - last.mx, now.my - last.my);
        if (now.dist > 0 && last.dist > 0) zoom(last.dist / now.dist);
      }
      last = now;
    } else if (mode === 'pan') {
      pan(e.clientX - prev.x, e.clientY - prev.y);
    } else if (mode === 'orbit') {
      orbit(e.clientX - prev.x, e.clientY - prev.y);
    }
  });
  const end = (e) => {
    pointers.delete(e.pointerId);
    if (pointers.size === 0) { mode = null; el.classList.remove('dragging'); moved(false); }
    last = null;
  };
  el.addEventListener('pointerup', end);
  el.addEventListener('pointercancel', end);
  el.addEventListener('wheel', (e) => { e.preventDefault(); zoom(Math.exp(e.deltaY * 0.001)); }, { passive: false });
}

function jump(split, index) {
  const cams = S.info.runs[0].cameras[split] || [];
  if (index < 0 || index >= cams.length) { S.error = `split ${split} has ${cams.length} cameras`; updateStats(); return; }
  const c = cams[index];
  const sx = S.base.w / c.w, sy = S.base.h / c.h;
  S.cam = { R: c.R.slice(), C: c.C.slice(), K: [c.K[0] * sx, c.K[1] * sy, c.K[2] * sx, c.K[3] * sy] };
  const f = c.R.slice(6, 9);
  const toTarget = v3.sub(S.info.runs[0].target, c.C);
  let depth = v3.dot(toTarget, f);
  if (!(depth > 1e-3)) depth = v3.len(toTarget) || 1;
  S.target = v3.add(c.C, v3.mul(f, depth));
  S.dataset = { split, index };
  S.cameraTime = c.t;
  setTime(c.t);
  pump();
}

function setTime(t) {
  S.t = Math.round(t * 1e6) / 1e6;
  $('time').value = String(S.t);
  $('time-value').textContent = S.t.toFixed(3);
}

let lastFrame = null;
function tick(now) {
  if (!S.playing) { lastFrame = null; return; }
  if (lastFrame != null) {
    let t = S.t + ((now - lastFrame) / 1000) * S.speed / PERIOD_S;
    if (t > 1) t -= Math.floor(t);
    setTime(t);
    pump();
  }
  lastFrame = now;
  requestAnimationFrame(tick);
}

function setPlaying(on) {
  S.playing = on;
  $('play').textContent = on ? '⏸' : '▶';
  if (on) requestAnimationFrame(tick); else pump();
}

function download(blob, name) {
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob);
  a.download = name;
  document.body.appendChild(a);
  a.click();
  setTimeout(() => { URL.revokeObjectURL(a.href); a.remove(); }, 1000);
}

async function refreshInfo() {
  try {
    const res = await fetch('/api/info');
    const info = await res.json();
    const versions = info.runs.map((r) => r.version);
    const changed = S.versions.length && versions.some((v, i) => v !== S.versions[i]);
    S.info = info;
    S.versions = versions;
    if (changed) S.panes.forEach((p) => { p.shown = ''; });
    updateStats();
    pump();
  } catch (e) { S.error = `info: ${e}`; }
}

async function init() {
  const res = await fetch('/api/info');
  S.info = await res.json();
  S.runs = S.info.runs.length;
  S.versions = S.info.runs.map((r) => r.version);
  S.lastMs = S.info.runs.map(() => null);
  const r0 = S.info.runs[0];
  S.base = { w: r0.width, h: r0.height };
  S.scale = autoScale(r0.width);
  $('scale').value = String(S.scale);
  S.up = v3.norm(r0.up);
  makePanes();
  const start = (r0.cameras.test || []).length ? 'test' : 'train';
  $('split').value = start;
  jump(start, 0);
  $('time').addEventListener('input', () => { setTime(Number($('time').value)); moved(false); });
  $('time').addEventListener('change', () => { S.moving = false; pump(); });
  $('play').addEventListener('click', () => setPlaying(!S.playing));
  $('speed').addEventListener('change', () => { S.speed = Number($('speed').value); });
  $('scale').addEventListener('change', () => { S.scale = Number($('scale').value); layout(); pump(); });
  $('preview').addEventListener('change', pump);
  $('controls-label').hidden = !S.info.runs.some((r) => r.control_points != null);
  $('controls').addEventListener('change', () => { updateStats(); pump(); });
  $('jump').addEventListener('click', () => jump($('split').value, Number($('index').value)));
  $('reset').addEventListener('click', () => jump(start, 0));
  $('save-png').addEventListener('click', async () => {
    const res = await fetch(renderUrl(0, false).replace('&fmt=png', '') + '&fmt=png');
    if (res.ok) download(await res.blob(), `view_t${S.t.toFixed(3)}.png`);
  });
  $('save-camera').addEventListener('click', async () => {
    const res = await fetch(`/api/camera?${cameraQuery(size(false))}`);
    if (res.ok) download(await res.blob(), 'camera.json');
  });
  document.addEventListener('keydown', (e) => {
    if (e.code === 'Space' && e.target === document.body) { e.preventDefault(); setPlaying(!S.playing); }
  });
  setInterval(refreshInfo, 2000);
  updateStats();
}

// For the browser test and for scripting from the console.
window.evogsView = {
  settled: () => !!S.info && !S.moving && !S.playing && S.panes.every((p) =>
    !p.inflight && p.shown === renderUrl(S.panes.indexOf(p), false) && p.img.complete && p.img.naturalWidth > 0),
  urls: () => S.panes.map((_, i) => renderUrl(i, false)),
  state: () => ({ cam: S.cam, t: S.t, dataset: S.dataset, size: size(false) }),
  info: () => S.info,
};

init().catch((e) => { $('stats').textContent = `cannot start: ${e}`; });
