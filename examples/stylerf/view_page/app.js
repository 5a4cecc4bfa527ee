// stylerf view: the page of `stylerf view` (the HTTP API is docs/viewer.md). Plain JavaScript, nothing from
// the network: the server embeds this file and serves it beside index.html.
'use strict';

// Timestamps for the tests and the benchmark, read with WebDriver: every frame shown, with when it was asked
// for and when it reached the canvas (performance.now() milliseconds).
const stats = { loadedAt: performance.now(), infoAt: null, frames: [], uploads: [] };
window.stylerfStats = stats;

const SETTLE_MS = 150; // a camera still this long gets its full-size frame

// The server may require a token (`--host`): the page got it in its own URL and passes it on.
const token = new URLSearchParams(location.search).get('token');

// One id per tab: the server keeps one request slot per client, so a newer frame replaces this tab's older one.
const client = 'tab-' + Array.from(crypto.getRandomValues(new Uint8Array(6)),
  (b) => b.toString(16).padStart(2, '0')).join('');

const $ = (id) => document.getElementById(id);
const canvas = $('view');
const ctx = canvas.getContext('2d');

let info = null; // GET /api/info
let styles = []; // [{id, name, source}], in strip order

// What the frame shows; the page's controls write it, window.stylerfState reads it.
const state = {
  camera: { view: 0, yaw: 0, pitch: 0, zoom: 0 },
  style: null,
  styleB: null,
  mix: 0,
  region: { on: false, shape: 'box', scale: 1 },
};
window.stylerfState = state;

// ---- requests --------------------------------------------------------------------------------------------

function withToken(url) {
  if (!token) return url;
  return url + (url.includes('?') ? '&' : '?') + 'token=' + encodeURIComponent(token);
}

function api(path, opts = {}) {
  const headers = Object.assign({}, opts.headers || {});
  if (token) headers['X-Stylerf-Token'] = token;
  return fetch(path, Object.assign({}, opts, { headers }));
}

function postJson(path, body) {
  return api(path, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) });
}

// The server's refusal message ({"error": ...}), or the status line when the body is not that JSON.
async function errorText(resp) {
  try {
    const j = await resp.json();
    if (j && typeof j.error === 'string') return j.error;
  } catch (e) { /* not JSON: fall through */ }
  return `${resp.status} ${resp.statusText}`;
}

let errorFromRender = false;
function showError(msg, fromRender = false) {
  $('error').textContent = msg;
  errorFromRender = fromRender;
}
function clearError() {
  $('error').textContent = '';
  errorFromRender = false;
}

function download(blob, name) {
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob);
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
}

// ---- frames: previews while things change, the full frame once they stop ------------------------------------

const fullSide = () => Math.max(info.full.width, info.full.height);

function renderBody(side) {
  const body = { client, camera: Object.assign({}, state.camera), side, style: state.style };
  if (state.styleB) {
    body.style_b = state.styleB;
    if (state.region.on) body.region = { shape: state.region.shape, scale: state.region.scale };
    else body.mix = state.mix;
  }
  return body;
}

// Only what changes the picture: moving the mix slider without a style B asks for nothing.
function stateKey() {
  const b = renderBody(0);
  delete b.side;
  return JSON.stringify(b);
}

let version = 0;        // bumped on every change of what the frame shows
let lastKey = '';
let lastChangeAt = 0;
let seq = 0;            // request number; an answer older than the frame on the canvas is dropped
let shownSeq = 0;
let inFlight = null;    // the newest request sent and not yet answered
let pending = false;    // something changed while a preview was in flight: send the newest when it answers
let fullSentFor = -1;   // the version whose full frame was asked for (once per version)
let settleTimer = 0;
let lastFull = null;    // {blob, version}: what "Save frame" saves
let saveWanted = false; // "Save frame" before any full frame of this state: save the next one

function changed() {
  if (!info || !state.style) return;
  const key = stateKey();
  if (key === lastKey) return;
  lastKey = key;
  version++;
  lastChangeAt = performance.now();
  clearTimeout(settleTimer);
  // At most one request in flight: a preview in flight is left to finish (it is the freshest feedback we
  // will get soonest) and the newest state goes out when it answers. A full frame in flight is slow and
  // now stale, so the new preview goes out at once; the server cancels the full one (409).
  if (inFlight && inFlight.kind === 'preview') pending = true;
  else send('preview');
}

function send(kind) {
  const side = kind === 'full' ? fullSide() : Math.min(info.preview_side, fullSide());
  const req = { seq: ++seq, kind, side, version, requestedAt: performance.now(), body: renderBody(side) };
  if (kind === 'full') fullSentFor = version;
  inFlight = req;
  postJson('/api/render', req.body)
    .then((resp) => answered(req, resp))
    .catch((e) => showError(`render failed: ${e.message || e}`, true))
    .finally(() => {
      if (inFlight !== req) return; // a newer request took over
      inFlight = null;
      next();
    });
}

// What to send once nothing is in flight: the newest preview if the state moved on, else the full frame after
// the state has been still for SETTLE_MS.
function next() {
  if (pending) {
    pending = false;
    send('preview');
    return;
  }
  if (fullSentFor === version) return;
  const wait = Math.max(0, lastChangeAt + SETTLE_MS - performance.now());
  const v = version;
  clearTimeout(settleTimer);
  settleTimer = setTimeout(() => {
    if (v === version && !inFlight) send('full');
  }, wait);
}

async function answered(req, resp) {
  if (resp.status === 409) return; // superseded by this tab's newer request: expected, not an error
  if (!resp.ok) {
    showError(`render: ${await errorText(resp)}`, true);
    return;
  }
  const blob = await resp.blob();
  const bitmap = await decode(blob);
  if (req.seq < shownSeq) { // a newer frame is already on the canvas
    if (bitmap.close) bitmap.close();
    return;
  }
  shownSeq = req.seq;
  const { width, height } = bitmap; // draw() releases the bitmap
  draw(bitmap);
  const frame = {
    kind: req.kind, side: req.side, width, height,
    requestedAt: req.requestedAt, shownAt: performance.now(),
    renderMs: Number(resp.headers.get('X-Render-Ms')), cached: resp.headers.get('X-Content-Cached') === '1',
    camera: req.body.camera, style: req.body.style, styleB: req.body.style_b || null,
    mix: req.body.mix === undefined ? 0 : req.body.mix, region: req.body.region || null,
  };
  stats.frames.push(frame);
  showStatus(frame);
  if (errorFromRender) clearError();
  if (req.kind === 'full') {
    lastFull = { blob, version: req.version };
    if (saveWanted) {
      saveWanted = false;
      download(blob, 'stylerf_frame.png');
    }
  }
}

// No colour management: the canvas must hold the PNG's own values, so that a full frame read back with
// getImageData equals what the server rendered.
function decode(blob) {
  if (window.createImageBitmap) {
    return createImageBitmap(blob, { colorSpaceConversion: 'none', premultiplyAlpha: 'none' });
  }
  return new Promise((resolve, reject) => {
    const img = new Image();
    img.onload = () => resolve(img);
    img.onerror = () => reject(new Error('the frame is not an image'));
    img.src = URL.createObjectURL(blob);
  });
}

// Previews are smaller than the canvas and scaled up; the full frame has the canvas's size and lands 1:1.
function draw(bitmap) {
  ctx.imageSmoothingEnabled = true;
  ctx.imageSmoothingQuality = 'high';
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.drawImage(bitmap, 0, 0, canvas.width, canvas.height);
  if (bitmap.close) bitmap.close();
}

function showStatus(f) {
  const rt = Math.round(f.shownAt - f.requestedAt);
  $('status').textContent = `${f.kind} ${f.width}×${f.height} (side ${f.side}) · ` +
    `render ${f.renderMs.toFixed(1)} ms · round trip ${rt} ms · content ${f.cached ? 'cached' : 'rendered'} · ` +
    info.device;
}

window.stylerfRequestFull = () => {
  if (!info || !state.style) return;
  clearTimeout(settleTimer);
  pending = false;
  send('full');
};

// ---- camera ----------------------------------------------------------------------------------------------

const clamp = (x, [lo, hi]) => Math.min(hi, Math.max(lo, x));

function moveCamera(dyaw, dpitch, dzoom) {
  const c = state.camera;
  c.yaw = clamp(c.yaw + dyaw, info.limits.yaw);
  c.pitch = clamp(c.pitch + dpitch, info.limits.pitch);
  c.zoom = clamp(c.zoom + dzoom, info.limits.zoom);
  changed();
}

let drag = null; // {id, x, y} of the pointer that holds the canvas

canvas.addEventListener('pointerdown', (e) => {
  if (!info || e.button !== 0) return;
  canvas.setPointerCapture(e.pointerId); // keep getting moves when the pointer leaves the canvas
  drag = { id: e.pointerId, x: e.clientX, y: e.clientY };
  canvas.classList.add('dragging');
});

canvas.addEventListener('pointermove', (e) => {
  if (!drag || e.pointerId !== drag.id) return;
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  drag.x = e.clientX;
  drag.y = e.clientY;
  if (!dx && !dy) return;
  if (info.kind === 'orbit') {
    moveCamera(-dx * 0.01, dy * 0.01, 0); // radians: a 100 px drag turns about 57 degrees
  } else {
    // Forward-facing: the offsets span [-1, 1] over the capture's range, so one canvas width is the full range.
    const r = canvas.getBoundingClientRect();
    moveCamera(dx / r.width * 2, -dy / r.height * 2, 0);
  }
});

function endDrag(e) {
  if (!drag || e.pointerId !== drag.id) return;
  drag = null;
  canvas.classList.remove('dragging');
}
canvas.addEventListener('pointerup', endDrag);
canvas.addEventListener('pointercancel', endDrag);
canvas.addEventListener('lostpointercapture', endDrag);

canvas.addEventListener('wheel', (e) => {
  if (!info) return;
  e.preventDefault(); // the wheel zooms the scene, not the page
  moveCamera(0, 0, -e.deltaY * 0.001);
}, { passive: false });

function snapToView() {
  const n = Math.round(Number($('view-index').value));
  const view = Math.min(info.views - 1, Math.max(0, Number.isFinite(n) ? n : 0));
  $('view-index').value = view;
  state.camera = { view, yaw: 0, pitch: 0, zoom: 0 };
  changed();
}
$('training-view').addEventListener('click', () => info && snapToView());
$('view-index').addEventListener('change', () => info && snapToView());

// The canvas keeps the frame's pixel size; CSS scales it to the largest size the window fits.
function fitCanvas() {
  if (!info) return;
  const r = $('stage').getBoundingClientRect();
  const s = Math.max(0.01, Math.min(r.width / info.full.width, r.height / info.full.height));
  canvas.style.width = `${Math.floor(info.full.width * s)}px`;
  canvas.style.height = `${Math.floor(info.full.height * s)}px`;
}
// The stage changes size with the window and with the toolbar and strip above and below it (thumbnails load
// late), so its own size is watched, not the window's.
new ResizeObserver(fitCanvas).observe($('stage'));

// ---- styles ----------------------------------------------------------------------------------------------

function styleLabel(s) {
  return s.source === 'folder' ? s.name : `${s.name} (${s.source})`;
}

function addStyle(s) {
  styles.push(s);
  const btn = document.createElement('button');
  btn.type = 'button';
  btn.className = 'thumb';
  btn.dataset.id = s.id;
  btn.title = `${styleLabel(s)}: click for style A, shift-click for style B`;
  const img = document.createElement('img');
  img.alt = s.name;
  img.src = withToken(`/api/styles/${encodeURIComponent(s.id)}/thumb`);
  const name = document.createElement('span');
  name.className = 'name';
  name.textContent = s.name;
  btn.append(img, name);
  for (const which of ['a', 'b']) {
    const badge = document.createElement('span');
    badge.className = `badge ${which}`;
    badge.textContent = which.toUpperCase();
    btn.append(badge);
  }
  btn.addEventListener('click', (e) => (e.shiftKey ? setStyleB(s.id) : setStyleA(s.id)));
  $('styles').append(btn);
  for (const id of ['style-a', 'style-b']) $(id).append(new Option(styleLabel(s), s.id));
}

// The strip's badges and the two selects show the same choice, whichever of them made it.
function syncStyles() {
  $('style-a').value = state.style || '';
  $('style-b').value = state.styleB || '';
  for (const el of $('styles').children) {
    el.classList.toggle('a', el.dataset.id === state.style);
    el.classList.toggle('b', el.dataset.id === state.styleB);
  }
}

function setStyleA(id) {
  state.style = id;
  syncStyles();
  changed();
}

function setStyleB(id) {
  state.styleB = id || null;
  syncStyles();
  changed();
}

$('style-a').addEventListener('change', (e) => setStyleA(e.target.value));
$('style-b').addEventListener('change', (e) => setStyleB(e.target.value));

async function upload(file) {
  if (!file) return;
  clearError();
  const entry = { name: file.name, startedAt: performance.now(), doneAt: null, id: null };
  stats.uploads.push(entry);
  $('status').textContent = `encoding ${file.name}…`;
  try {
    const resp = await api('/api/styles?name=' + encodeURIComponent(file.name), {
      method: 'POST', body: file, headers: { 'Content-Type': file.type || 'application/octet-stream' },
    });
    if (resp.status !== 201) {
      entry.error = await errorText(resp);
      showError(`${file.name}: ${entry.error}`);
      return;
    }
    const s = await resp.json();
    Object.assign(entry, { id: s.id, doneAt: performance.now(), encodeMs: s.encode_ms });
    addStyle(s);
    setStyleA(s.id);
  } catch (e) {
    entry.error = String(e.message || e);
    showError(`${file.name}: upload failed: ${entry.error}`);
  }
}

$('upload').addEventListener('change', (e) => {
  const file = e.target.files[0];
  e.target.value = ''; // so that choosing the same file again uploads it again
  upload(file);
});

// An image dropped anywhere on the page becomes a style.
document.addEventListener('dragover', (e) => {
  e.preventDefault();
  document.body.classList.add('dropping');
});
document.addEventListener('dragleave', (e) => {
  if (!e.relatedTarget) document.body.classList.remove('dropping'); // left the window
});
document.addEventListener('drop', (e) => {
  e.preventDefault();
  document.body.classList.remove('dropping');
  const files = Array.from(e.dataTransfer.files);
  // Not an image by its type? Send it anyway: the server says what is wrong with it.
  upload(files.find((f) => f.type.startsWith('image/')) || files[0]);
});

// ---- mix and region --------------------------------------------------------------------------------------

function readMix() {
  state.mix = Number($('mix').value) / 100;
  $('mix-value').textContent = state.mix.toFixed(2);
  changed();
}
$('mix').addEventListener('input', readMix);
$('mix').addEventListener('change', readMix);

function readRegion() {
  state.region = {
    on: $('region').checked,
    shape: $('region-shape').value,
    scale: Number($('region-scale').value) / 100,
  };
  $('region-scale-value').textContent = state.region.scale.toFixed(2);
  changed();
}
for (const id of ['region', 'region-shape', 'region-scale']) {
  $(id).addEventListener('input', readRegion);
  $(id).addEventListener('change', readRegion);
}

// ---- save and record -------------------------------------------------------------------------------------

$('save').addEventListener('click', () => {
  if (!info) return;
  if (lastFull && lastFull.version === version) {
    download(lastFull.blob, 'stylerf_frame.png');
  } else {
    saveWanted = true; // no full frame of what is on screen yet: save the one asked for now
    window.stylerfRequestFull();
  }
});

$('record').addEventListener('click', async () => {
  if (!info || !state.style) return;
  const btn = $('record');
  btn.disabled = true;
  btn.textContent = 'recording…';
  clearError();
  try {
    const side = Math.min(info.preview_side * 2, fullSide());
    // Its own client id: a recording takes a while and must not be cancelled by this tab's next frame.
    const body = Object.assign(renderBody(side), { client: `${client}-rec`, frames: 36 });
    const resp = await postJson('/api/record', body);
    if (!resp.ok) showError(`record: ${await errorText(resp)}`);
    else download(await resp.blob(), 'stylerf_orbit.mp4');
  } catch (e) {
    showError(`record failed: ${e.message || e}`);
  } finally {
    btn.disabled = false;
    btn.textContent = 'Record';
  }
});

// ---- start -----------------------------------------------------------------------------------------------

async function start() {
  let resp;
  try {
    resp = await api('/api/info');
  } catch (e) {
    showError(`cannot reach the server: ${e.message || e}`);
    return;
  }
  if (!resp.ok) {
    showError(`/api/info: ${await errorText(resp)}`);
    return;
  }
  info = await resp.json();
  stats.infoAt = performance.now();
  canvas.width = info.full.width;
  canvas.height = info.full.height;
  fitCanvas();
  $('view-index').max = Math.max(0, info.views - 1);
  document.title = `stylerf view: ${info.scene}`;
  for (const s of info.styles) addStyle(s);
  state.style = styles.length ? styles[0].id : null;
  syncStyles();
  $('status').textContent = info.device;
  if (!state.style) {
    showError('the server has no styles: add one with "Add style…" or by dropping an image here');
    return;
  }
  changed();
}

start();
