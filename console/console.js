// kogei console: the page (docs/console.md). Everything it does goes through the
// console's API on the same origin; no other site is contacted.
'use strict';
const token = new URLSearchParams(location.search).get('token');
const $ = (id) => document.getElementById(id);
const stats = { frames: 0, fps: 0, latencyMs: 0, latencies: [], seq: 0, sequences: [], times: [] };
window.kogeiStats = stats;
let roi = [0.4, 0.4, 0.6, 0.6];
let chart = null;
let state = null;
let img = null;

function withToken(url) {
  if (!token) return url;
  return url + (url.includes('?') ? '&' : '?') + 'token=' + encodeURIComponent(token);
}
async function api(path, body) {
  const opts = { headers: {} };
  if (token) opts.headers['X-Kogei-Token'] = token;
  if (body !== undefined) {
    opts.method = 'POST';
    opts.headers['Content-Type'] = 'application/json';
    opts.body = JSON.stringify(body);
  }
  const r = await fetch(path, opts);
  const j = await r.json();
  if (!r.ok) throw new Error(j.error || r.statusText);
  return j;
}
function fmt(v, d) { return v === null || v === undefined ? '–' : Number(v).toFixed(d); }

// ---- views ----
for (const b of document.querySelectorAll('nav button')) {
  b.addEventListener('click', () => showView(b.dataset.view));
}
function showView(name) {
  for (const b of document.querySelectorAll('nav button')) b.classList.toggle('active', b.dataset.view === name);
  for (const s of document.querySelectorAll('.view')) s.hidden = s.id !== 'view-' + name;
  if (name === 'session') loadSession();
}
window.kogeiShowView = showView;

// ---- live view ----
const canvas = $('live');
const ctx = canvas.getContext('2d');
function draw() {
  if (!img) return;
  if (canvas.width !== img.width || canvas.height !== img.height) {
    canvas.width = img.width; canvas.height = img.height;
  }
  ctx.drawImage(img, 0, 0);
  const W = canvas.width, H = canvas.height;
  ctx.lineWidth = 2;
  ctx.strokeStyle = '#3fa0ff';
  ctx.strokeRect(roi[0] * W, roi[1] * H, (roi[2] - roi[0]) * W, (roi[3] - roi[1]) * H);
  if (chart && chart.found) {
    const poly = (pts, colour) => {
      ctx.strokeStyle = colour; ctx.beginPath();
      pts.forEach((p, i) => (i ? ctx.lineTo : ctx.moveTo).call(ctx, p[0] * W, p[1] * H));
      ctx.closePath(); ctx.stroke();
    };
    poly(chart.outline, '#ffffff');
    for (const t of chart.tags) poly(t.corners, t.used ? '#30d158' : '#ff9f0a');
    ctx.font = '11px sans-serif';
    for (const p of chart.patches) {
      const bad = p.flags !== 0;
      poly(p.quad, bad ? '#ff3b30' : '#ffd60a');
      ctx.fillStyle = bad ? '#ff3b30' : '#ffd60a';
      ctx.fillText(p.id, p.quad[0][0] * W + 2, p.quad[0][1] * H + 11);
    }
  }
}
let drag = null;
canvas.addEventListener('mousedown', (e) => {
  const r = canvas.getBoundingClientRect();
  drag = [(e.clientX - r.left) / r.width, (e.clientY - r.top) / r.height];
});
canvas.addEventListener('mouseup', (e) => {
  if (!drag) return;
  const r = canvas.getBoundingClientRect();
  const x = (e.clientX - r.left) / r.width, y = (e.clientY - r.top) / r.height;
  const x0 = Math.min(drag[0], x), x1 = Math.max(drag[0], x), y0 = Math.min(drag[1], y), y1 = Math.max(drag[1], y);
  if (x1 - x0 > 0.01 && y1 - y0 > 0.01) { roi = [x0, y0, x1, y1].map((v) => Math.min(1, Math.max(0, v))); pushView(); }
  drag = null; draw();
});
$('ev').addEventListener('input', () => { $('evtext').textContent = $('ev').value; pushView(); });
$('peaking').addEventListener('change', () => pushView());

// The view (display EV, peaking, focus region) is a state change: POST /api/view,
// one request at a time, the latest values sent when the one in flight returns.
let viewBusy = false, viewAgain = false;
async function pushView() {
  if (viewBusy) { viewAgain = true; return; }
  viewBusy = true;
  try {
    do {
      viewAgain = false;
      await api('/api/view', { ev: Number($('ev').value), peaking: $('peaking').checked, roi: roi });
    } while (viewAgain);
  } catch (e) { setStatus('view: ' + e.message, true); }
  viewBusy = false;
}

function drawHist(h) {
  const c = $('hist'), g = c.getContext('2d');
  g.fillStyle = '#111'; g.fillRect(0, 0, c.width, c.height);
  if (!h) return;
  const colours = h.length === 1 ? ['#ddd'] : ['rgba(255,80,80,0.8)', 'rgba(80,255,80,0.8)', 'rgba(90,140,255,0.8)'];
  const max = Math.max(1, ...h.flat().map((v) => Math.log1p(v)));
  h.forEach((bins, ch) => {
    g.strokeStyle = colours[ch]; g.beginPath();
    bins.forEach((v, i) => {
      const x = (i + 0.5) * c.width / bins.length, y = c.height - Math.log1p(v) / max * (c.height - 4);
      (i ? g.lineTo : g.moveTo).call(g, x, y);
    });
    g.stroke();
  });
}

function showLive(j) {
  const s = j.settings || {};
  const rows = [];
  if (s.model) rows.push(['camera', s.model + ' (' + s.serial + ')']);
  if (s.format) rows.push(['format', s.format.pixfmt + ' ' + s.format.cfa + ' ' + s.format.bits + ' bits ' + s.format.width + '×' + s.format.height]);
  if (s.exposure_us) rows.push(['exposure', fmt(s.exposure_us.value, 1) + ' µs']);
  if (s.gain) rows.push(['gain', fmt(s.gain.value, 2) + ' ' + s.gain.unit]);
  rows.push(['frame', (j.sequence ?? '–') + (j.paused ? ' (paused: a capture owns the camera)' : '')]);
  $('readback').innerHTML = '';
  for (const [k, v] of rows) {
    const tr = document.createElement('tr');
    tr.innerHTML = '<th></th><td></td>';
    tr.children[0].textContent = k; tr.children[1].textContent = v;
    $('readback').appendChild(tr);
  }
  $('focus').textContent = j.focus === null || j.focus === undefined ? '–' : Number(j.focus).toPrecision(4);
  $('clipped').textContent = 'clipped samples: ' + fmt(100 * (j.clipped_fraction || 0), 3) + ' %';
  drawHist(j.histograms);
  $('liveinfo').textContent = (j.error ? 'camera: ' + j.error + ' — ' : '') +
    'preview ' + (j.preview_width || 0) + '×' + (j.preview_height || 0) + ' (binning ' + (j.binning || '–') +
    '), server ' + fmt(j.server_ms, 1) + ' ms, page ' + fmt(stats.fps, 1) + ' fps, latency ' + fmt(stats.latencyMs, 0) + ' ms';
}

// The live view: GET /api/preview?after=N answers with the first preview newer than N
// (a long poll), its numbers in headers. The next request leaves as soon as an answer
// arrives, while the image is decoded (createImageBitmap) and drawn at the next
// animation frame; a preview arriving before that frame replaces the one waiting.
// stats: previews drawn, their rate over 5 s and their latency (the frame's arrival
// from the camera driver, X-Kogei-Captured-Ms, to the frame it is drawn in).
let shown = null, lastInfo = 0;
function fetchPreview(after) {
  const opts = { headers: {} };
  if (token) opts.headers['X-Kogei-Token'] = token;
  return fetch('/api/preview?after=' + after, opts);
}
function present(bmp, meta) {
  const first = !shown;
  if (shown) shown.bmp.close();
  shown = { bmp: bmp, meta: meta };
  if (!first) return;
  requestAnimationFrame(() => {
    const s = shown; shown = null;
    if (img) img.close();
    img = s.bmp;
    draw();
    const now = performance.timeOrigin + performance.now();
    stats.seq = Math.max(stats.seq, s.meta.n);
    stats.frames++;
    stats.latencyMs = now - s.meta.captured;
    stats.latencies.push(stats.latencyMs); // every preview's, the last 20000
    if (stats.latencies.length > 20000) stats.latencies.splice(0, 10000);
    stats.sequences.push(s.meta.sequence);
    if (stats.sequences.length > 50) stats.sequences.shift();
    const t = performance.now();
    stats.times.push(t);
    while (stats.times.length && t - stats.times[0] > 5000) stats.times.shift();
    if (stats.times.length > 1) stats.fps = (stats.times.length - 1) * 1000 / (t - stats.times[0]);
    if (s.meta.live && t - lastInfo > 100) { lastInfo = t; showLive(s.meta.live); }
  });
}
async function liveLoop() {
  let after = 0, pending = fetchPreview(0);
  for (;;) {
    try {
      const r = await pending;
      if (!r.ok) {
        const j = await r.json().catch(() => ({}));
        $('liveinfo').textContent = 'live view: ' + (j.error || r.statusText);
        if (r.status === 503) {
          // no preview: the camera's state (paused by a capture, an error) says why
          try { showLive(await api('/api/live')); } catch (e) { /* shown above */ }
        } else {
          await new Promise((ok) => setTimeout(ok, 1000));
        }
        pending = fetchPreview(after);
        continue;
      }
      const n = Number(r.headers.get('X-Kogei-Preview'));
      const meta = { n: n, captured: Number(r.headers.get('X-Kogei-Captured-Ms')) };
      const text = r.headers.get('X-Kogei-Live');
      if (text) { meta.live = JSON.parse(text); meta.sequence = meta.live.sequence; }
      after = Math.max(after, n);
      pending = fetchPreview(after);
      present(await createImageBitmap(await r.blob()), meta);
    } catch (e) {
      $('liveinfo').textContent = 'live view: ' + e.message;
      await new Promise((ok) => setTimeout(ok, 1000));
      pending = fetchPreview(after);
    }
  }
}

$('apply').addEventListener('click', async () => {
  const body = {};
  if ($('exposure').value) body.exposure_us = Number($('exposure').value);
  if ($('gain').value) body.gain = Number($('gain').value);
  try { await api('/api/settings', body); setStatus('settings applied'); } catch (e) { setStatus(e.message, true); }
});
$('camera').addEventListener('change', async () => {
  try { await api('/api/settings', { camera: Number($('camera').value) }); chart = null; } catch (e) { setStatus(e.message, true); }
});

// ---- chart check ----
$('check').addEventListener('click', async () => {
  $('verdict').textContent = 'looking for the chart…'; $('verdict').className = '';
  try {
    chart = await api('/api/chart');
  } catch (e) { chart = { go: false, error: e.message, reasons: [] }; }
  $('verdict').textContent = chart.go ? 'GO: the chart is found and every patch is usable' : 'NO GO';
  $('verdict').className = chart.go ? 'go' : 'nogo';
  const ul = $('chartinfo'); ul.innerHTML = '';
  const add = (t) => { const li = document.createElement('li'); li.textContent = t; ul.appendChild(li); };
  if (chart.error) add(chart.error);
  if (chart.found) add('tags used: ' + chart.tags_used + (chart.tagless ? ' (tagless)' : '') + ', ' + chart.patches.length + ' patches, ' + chart.flagged + ' flagged');
  for (const r of chart.reasons || []) add(r);
  for (const w of chart.warnings || []) add('note: ' + w);
  draw();
});

// ---- captures ----
$('start').addEventListener('click', async () => {
  const body = { kind: $('kind').value, frames: Number($('frames').value || 10), camera: Number($('camera').value) };
  if ($('cexposure').value) body.exposure_us = Number($('cexposure').value);
  if ($('auto').checked) body.auto_exposure = true;
  if ($('cname').value) body.name = $('cname').value;
  if ($('cflat').value) body.flat = $('cflat').value;
  // the object record: the known keys, then KEY=VALUE lines (the server checks them)
  const meta = {};
  for (const k of ['accession', 'title', 'operator', 'lighting', 'notes'])
    if ($('m-' + k).value) meta[k] = $('m-' + k).value;
  for (const line of $('m-more').value.split('\n')) {
    if (!line.trim()) continue;
    const eq = line.indexOf('=');
    if (eq < 0) { setStatus('Other keys: "' + line + '": expected KEY=VALUE', true); return; }
    meta[line.slice(0, eq).trim()] = line.slice(eq + 1);
  }
  if (Object.keys(meta).length) body.meta = meta;
  try { showState(await api('/api/capture', body)); } catch (e) { setStatus(e.message, true); }
});

// ---- spectrometer ----
$('mstart').addEventListener('click', async () => {
  try { showState(await api('/api/measure', { resume: $('resume').checked })); } catch (e) { setStatus(e.message, true); }
});
for (const [id, a] of [['am', 'm'], ['ar', 'r'], ['aw', 'w'], ['aq', 'q']]) {
  $(id).addEventListener('click', async () => {
    try { showState(await api('/api/measure/answer', { answer: a })); } catch (e) { setStatus(e.message, true); }
  });
}

// ---- session ----
async function loadSession() {
  try {
    const j = await api('/api/session');
    $('sessiondir').textContent = j.session;
    const tb = $('captures').querySelector('tbody'); tb.innerHTML = '';
    for (const c of (j.manifest.captures || [])) {
      const st = c.statistics || {}, s = c.settings || {}, str = st.stream || {}, co = c.corrections || {};
      const cells = [c.name, c.kind, c.frames ? c.frames.length : s.frames, fmt(s.exposure_us, 0),
        fmt(100 * (st.clipped_fraction || 0), 3), fmt(100 * (st.underexposed_fraction || 0), 2),
        (str.completed ?? 0) + ' ok, ' + (str.dropped ?? 0) + ' dropped',
        (co.dark || '–') + ' / ' + (co.flat || '–')];
      const tr = document.createElement('tr');
      for (const v of cells) { const td = document.createElement('td'); td.textContent = v; tr.appendChild(td); }
      tb.appendChild(tr);
    }
  } catch (e) { setStatus(e.message, true); }
}
$('process').addEventListener('click', async () => {
  try { showState(await api('/api/process', {})); } catch (e) { setStatus(e.message, true); }
});
$('reportlink').addEventListener('click', (e) => {
  e.preventDefault();
  const f = $('report'); f.src = withToken('/out/report.html'); f.hidden = false; f.scrollIntoView();
});

// ---- state ----
function setStatus(text, bad) { $('status').textContent = text; $('status').style.color = bad ? '#ff7b7b' : '#9fd49f'; }
let lastJobKey = '';
function showState(s) {
  state = s;
  const sel = $('camera');
  if (sel.options.length !== s.cameras.length) {
    sel.innerHTML = '';
    s.cameras.forEach((u, i) => { const o = document.createElement('option'); o.value = i; o.textContent = u; sel.appendChild(o); });
  }
  if (s.camera >= 0 && document.activeElement !== sel) sel.value = s.camera;
  $('layout').textContent = s.layout || 'none (--layout)';
  $('spectro').textContent = s.spectro || 'none (--spectro)';
  $('spectraout').textContent = s.spectra_out + (s.spectra_measured ? ' (measured)' : '') + (s.spectra_partial ? ' (interrupted: resume)' : '');
  if (!$('frames').value) $('frames').value = s.frames;
  $('capturehint').textContent = 'into ' + s.session;
  const j = s.job;
  $('jobtitle').textContent = j.title ? j.title + (j.running ? ' (running)' : j.error ? ' (failed)' : ' (done)') : 'none';
  $('jobprogress').value = j.n ? j.i / j.n : (j.running ? 0 : 1);
  $('joblog').textContent = j.log.join('\n');
  $('joblog').scrollTop = $('joblog').scrollHeight;
  const res = $('jobresult');
  res.innerHTML = '';
  if (j.error) { const p = document.createElement('p'); p.className = 'error'; p.textContent = j.error; res.appendChild(p); }
  if (j.result && j.kind === 'capture') {
    const st = j.result.statistics, str = st.stream;
    const p = document.createElement('p');
    p.textContent = j.result.name + ': clipped ' + fmt(100 * st.clipped_fraction, 4) + ' %, under-exposed ' +
      fmt(100 * st.underexposed_fraction, 2) + ' %, max ' + fmt(st.max, 4) + '; stream ' + str.completed + ' completed, ' +
      str.dropped + ' dropped, ' + str.incomplete + ' incomplete, ' + str.timeouts + ' timeouts';
    res.appendChild(p);
  } else if (j.result && j.kind === 'process') {
    const p = document.createElement('p');
    p.textContent = j.result.objects + ' object(s), ' + j.result.processed + ' processed; M2 residual ' + fmt(100 * j.result.residual, 2) + ' %; ' + j.result.warnings + ' warning(s)';
    res.appendChild(p);
  } else if (j.result && j.kind === 'measure') {
    const p = document.createElement('p'); p.textContent = j.result.patches + ' patches written to ' + j.result.file; res.appendChild(p);
  }
  $('prompt').hidden = !j.waiting;
  if (j.waiting) {
    $('prompttext').textContent = j.prompt;
    $('ar').disabled = !j.allowed.includes('r');
    $('aw').disabled = !j.allowed.includes('w');
  }
  $('reportlink').hidden = !s.report;
  const key = j.title + j.running;
  if (key !== lastJobKey) { lastJobKey = key; if (!j.running) loadSession(); }
}
async function stateLoop() {
  for (;;) {
    try { showState(await api('/api/state')); } catch (e) { setStatus(e.message, true); }
    await new Promise((ok) => setTimeout(ok, 500));
  }
}
stateLoop();
pushView();
liveLoop();
