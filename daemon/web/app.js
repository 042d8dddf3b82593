/* scicap web view: the state from /api/state, then live from /api/events (server-sent events, no polling).
 * State the headless test reads from the DOM: body[data-points] (points plotted for the current reconstruction),
 * body[data-points-while-running] (points that arrived before its recon.done), body[data-recon] (running|done),
 * #captures a[data-capture=ID], #recon-frames img[data-loaded]. */
'use strict';

const $ = (id) => document.getElementById(id);
let state = null;
let chart = null;
let current = null;      // {job, capture, method, points, truth}
let lastJob = null;      // the newest job this page started (for "cancel last job")
let refreshTimer = null;
let latest = null;       // the capture shown as the latest snapshot

function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

function fmt(x, digits) { return typeof x === 'number' && isFinite(x) ? x.toFixed(digits) : '–'; }

function scheduleRefresh(ms) {
  if (refreshTimer) return;
  refreshTimer = setTimeout(() => { refreshTimer = null; loadState(); }, ms);
}

async function loadState() {
  try {
    const r = await fetch('/api/state', {cache: 'no-store'});
    if (!r.ok) throw new Error('state: HTTP ' + r.status);
    state = await r.json();
    render();
  } catch (e) {
    $('summary').textContent = String(e);
  }
}

// The control form's methods come from the daemon's solver table; filled once, so a choice is not reset.
function renderMethods(methods) {
  const sel = $('method');
  if (sel.options.length || !methods.length) return;
  for (const m of methods) {
    const o = document.createElement('option');
    o.value = o.textContent = m.name;
    o.title = m.summary + (m.needs_camera ? ' (static 3-D scenes only)' : '');
    sel.appendChild(o);
  }
}

function render() {
  const s = state.status || {};
  $('summary').textContent = `scicapd ${s.version || ''} · up ${fmt(s.uptime_s, 0)} s · ` +
    `${s.captures_stored || 0} stored this run`;
  renderMethods(state.methods || []);
  renderDevices(s);
  renderJobs(state.jobs || []);
  renderCaptures(state.captures || {});
  $('control-card').hidden = !state.control;
}

function renderDevices(s) {
  const ul = $('devices');
  ul.replaceChildren();
  const devs = s.devices || {};
  for (const name of Object.keys(devs)) {
    const d = devs[name] || {};
    const id = d.identity || {};
    const li = el('li');
    li.append(el('b', {}, name + ' '));
    li.append(el('span', {class: d.connected ? 'ok' : 'bad'}, d.connected ? 'connected' : 'disconnected'));
    const what = [d.backend, id.model, id.serial, id.width && id.height ? `${id.width}×${id.height}` : '']
      .filter(Boolean).join(' · ');
    li.append(el('span', {class: 'muted'}, ' ' + what + (d.error ? ' — ' + d.error : '')));
    ul.append(li);
  }
  const q = s.queues || {};
  const fq = (v) => Array.isArray(v) ? `${v[0]}/${v[1]}` : '–';
  $('queues').textContent = `queues: capture ${fq(q.capture)}, reconstruction ${fq(q.reconstruction)}, ` +
    `storage ${fq(q.storage)} · workers busy ${s.workers_busy ?? '–'}`;
}

function renderJobs(jobs) {
  const tb = $('jobs');
  tb.replaceChildren();
  const shown = jobs.filter((j) => ['queued', 'running'].includes(j.state)).concat(
    jobs.filter((j) => !['queued', 'running'].includes(j.state)).slice(-6).reverse());
  for (const j of shown) {
    const tr = el('tr', {'data-job': j.job});
    const pct = j.total ? `${j.done}/${j.total}` : '';
    tr.append(el('td', {}, j.job), el('td', {}, j.kind), el('td', {}, j.state), el('td', {}, pct),
              el('td', {}, fmt(j.psnr, 2)));
    tb.append(tr);
  }
  if (!shown.length) tb.append(el('tr', {}, '')).firstChild.append(el('td', {colspan: 5, class: 'muted'}, 'no jobs'));
}

function renderCaptures(c) {
  const box = $('captures');
  const list = (c.captures || []).slice().reverse();
  $('captures-total').textContent = c.total !== undefined ? `${c.total} stored` : '';
  box.replaceChildren();
  for (const cap of list) {
    const a = el('a', {href: `/captures/${cap.capture}/preview_meas_000.png`, 'data-capture': cap.capture});
    a.append(el('img', {src: `/captures/${cap.capture}/preview_meas_000.png`, alt: cap.capture, loading: 'lazy'}));
    const best = (cap.recons || []).map((r) => r.psnr).filter((x) => typeof x === 'number');
    a.append(el('span', {}, cap.capture + (best.length ? ` · ${fmt(Math.max(...best), 1)} dB` : '')));
    box.append(a);
  }
  if (list.length && !current) showSnapshot(list[0].capture, list[0].truth);
}

function showSnapshot(id, truth) {
  latest = id;
  $('latest-id').textContent = id;
  $('latest-meas').src = `/captures/${id}/preview_meas_000.png`;
  const t = $('latest-truth');
  if (truth !== false) t.src = `/captures/${id}/preview_truth.gif`;
}

// Two curves against wall time: the residual ‖y − Ax‖/‖y‖ (every progress event; the only one without truth) and
// the PSNR when the solver's trace has it (with truth; some methods compute it only every few iterations).
// The sync report of the newest snapshot (capture.snapshot): the flags (or ok), whether the mask sequence fell
// inside the exposure, and the offset between them.
function showSync(ev) {
  const d = ev.data || {};
  const sync = Array.isArray(d.sync) ? d.sync.join(', ') : String(d.sync ?? '–');
  const off = typeof d.offset_ns === 'number' ? `${fmt(d.offset_ns / 1000, 1)} µs` : '–';
  const p = $('latest-sync');
  p.textContent = `sync of snapshot ${(d.index ?? 0) + 1}/${d.count ?? '?'} (job ${ev.job}): ${sync} · ` +
    `sequence ${d.inside ? 'inside' : 'NOT inside'} the exposure · offset ${off}` + (d.broken ? ' · broken' : '');
  p.className = sync === 'ok' && d.inside && !d.broken ? 'muted ok' : 'muted bad';
}

function makeChart() {
  if (chart) chart.destroy();
  chart = new Chart($('trace'), {
    type: 'line',
    data: {datasets: [
      {label: 'PSNR (dB)', data: [], yAxisID: 'psnr', borderColor: '#2f6fde', backgroundColor: '#2f6fde',
       pointRadius: 2, borderWidth: 2, tension: 0},
      {label: 'residual', data: [], yAxisID: 'res', borderColor: '#d9822b', backgroundColor: '#d9822b',
       pointRadius: 1.5, borderWidth: 1.5, tension: 0},
    ]},
    options: {
      animation: false, responsive: true, maintainAspectRatio: false, parsing: false,
      scales: {x: {type: 'linear', title: {display: true, text: 'wall time (s)'}},
               psnr: {type: 'linear', position: 'left', display: 'auto', title: {display: true, text: 'PSNR (dB)'}},
               res: {type: 'logarithmic', position: 'right', display: 'auto', grid: {drawOnChartArea: false},
                     title: {display: true, text: 'residual ‖y − Ax‖/‖y‖'}}},
      plugins: {legend: {display: true, position: 'bottom', labels: {boxWidth: 12}}},
    },
  });
}

function setPoints() {
  document.body.dataset.points = current ? current.points : 0;
}

function onReconStarted(ev) {
  const d = ev.data || {};
  current = {job: ev.job, capture: d.capture, method: d.method, points: 0, truth: null, done: false};
  document.body.dataset.recon = 'running';
  document.body.dataset.pointsWhileRunning = 0;
  $('recon-title').textContent = `job ${ev.job}: ${d.method} on ${d.capture}`;
  $('recon-frames').replaceChildren();
  $('recon-anim-box').hidden = true;
  $('recon-status').textContent = 'running';
  makeChart();
  setPoints();
  showSnapshot(d.capture);
}

function onReconProgress(ev) {
  const d = ev.data || {};
  if (!current || current.job !== ev.job || !chart || typeof d.elapsed_s !== 'number') return;
  const psnr = typeof d.psnr === 'number' && isFinite(d.psnr);
  if (psnr) chart.data.datasets[0].data.push({x: d.elapsed_s, y: d.psnr});
  if (typeof d.residual === 'number' && d.residual > 0) chart.data.datasets[1].data.push({x: d.elapsed_s, y: d.residual});
  chart.update('none');
  current.points++;
  setPoints();
  $('recon-status').textContent = `iteration ${d.iter}/${d.iters} · ${fmt(d.elapsed_s, 1)} s · ` +
    (psnr ? `PSNR ${fmt(d.psnr, 2)} dB · ` : '') + `residual ${fmt(d.residual, 4)}` +
    (typeof d.eta_s === 'number' ? ` · ${fmt(d.eta_s, 1)} s left` : '');
}

function frameCount(capture) {
  const c = ((state && state.captures && state.captures.captures) || []).find((x) => x.capture === capture);
  return c && c.frames ? c.frames : 8;
}

async function onReconDone(ev) {
  const d = ev.data || {};
  if (!current || current.job !== ev.job) {
    current = {job: ev.job, capture: d.capture, method: d.method, points: 0};
  }
  document.body.dataset.pointsWhileRunning = current.points;
  document.body.dataset.recon = 'done';
  $('recon-status').textContent = `done in ${fmt(d.solve_s, 2)} s` +
    (typeof d.psnr === 'number' ? ` · PSNR ${fmt(d.psnr, 2)} dB, SSIM ${fmt(d.ssim, 3)}` :
                                  ` · residual ${fmt(d.residual, 4)}`);
  await loadState();
  const box = $('recon-frames');
  box.replaceChildren();
  const n = frameCount(d.capture);
  for (let k = 0; k < n; k++) {
    const img = el('img', {alt: `frame ${k}`, 'data-loaded': '0'});
    img.addEventListener('load', () => img.setAttribute('data-loaded', '1'));
    img.addEventListener('error', () => img.setAttribute('data-loaded', 'error'));
    img.src = `/captures/${d.capture}/recon/${d.folder}/preview_${String(k).padStart(3, '0')}.png`;
    box.append(img);
  }
  $('recon-anim').src = `/captures/${d.capture}/recon/${d.folder}/preview.gif`;
  $('recon-anim-box').hidden = false;
  const cap = ((state && state.captures && state.captures.captures) || []).find((x) => x.capture === d.capture);
  if (cap && cap.truth) showDifference(d.capture, [...box.querySelectorAll('img')]);
}

// The difference to the truth, frame by frame, from the previews: the truth's animated GIF decoded with the
// browser's ImageDecoder (WebCodecs; without it, no difference row), each reconstructed frame's PNG once loaded.
function pixels(source, w, h) {
  const c = document.createElement('canvas');
  c.width = w; c.height = h;
  const g = c.getContext('2d');
  g.drawImage(source, 0, 0, w, h);
  return g.getImageData(0, 0, w, h);
}

function loaded(img) {
  return img.complete ? Promise.resolve() : new Promise((ok, bad) => {
    img.addEventListener('load', ok, {once: true});
    img.addEventListener('error', bad, {once: true});
  });
}

async function showDifference(capture, imgs) {
  const box = $('diff-frames');
  box.replaceChildren();
  $('diff-box').hidden = true;
  document.body.dataset.diff = 0;
  if (typeof ImageDecoder === 'undefined' || !imgs.length) return;
  try {
    const r = await fetch(`/captures/${capture}/preview_truth.gif`);
    if (!r.ok) return;
    const dec = new ImageDecoder({data: r.body, type: 'image/gif'});
    let drawn = 0;
    for (let k = 0; k < imgs.length; k++) {
      await loaded(imgs[k]);
      const w = imgs[k].naturalWidth, h = imgs[k].naturalHeight;
      const frame = (await dec.decode({frameIndex: k})).image;
      const t = pixels(frame, w, h);
      frame.close();
      const x = pixels(imgs[k], w, h);
      const c = document.createElement('canvas');
      c.width = w; c.height = h;
      const out = c.getContext('2d').createImageData(w, h);
      for (let i = 0; i < out.data.length; i += 4) {
        const v = Math.min(255, 4 * Math.abs(x.data[i] - t.data[i]));
        out.data[i] = out.data[i + 1] = out.data[i + 2] = v;
        out.data[i + 3] = 255;
      }
      c.getContext('2d').putImageData(out, 0, 0);
      c.setAttribute('aria-label', `difference, frame ${k}`);
      box.append(c);
      drawn++;
    }
    $('diff-box').hidden = false;
    document.body.dataset.diff = drawn;
  } catch (e) {
    $('recon-status').textContent += ` · no difference row: ${e.message || e}`;
  }
}

function onEvent(msg) {
  let ev;
  try { ev = JSON.parse(msg.data); } catch (e) { return; }
  switch (ev.event) {
    case 'recon.started': onReconStarted(ev); break;
    case 'recon.progress': onReconProgress(ev); return; // frequent: no state reload
    case 'recon.done': onReconDone(ev); return;
    case 'recon.failed': case 'recon.canceled':
      if (current && current.job === ev.job) {
        document.body.dataset.recon = ev.event.slice(6);
        $('recon-status').textContent = ev.event + (ev.data && ev.data.error ? ': ' + ev.data.error : '');
      }
      break;
    case 'capture.stored': showSnapshot(ev.data.capture); break;
    case 'capture.snapshot': showSync(ev); return; // its capture.stored follows
    default: break;
  }
  scheduleRefresh(300);
}

function connect() {
  const es = new EventSource('/api/events');
  es.addEventListener('open', () => { $('conn').textContent = 'live'; $('conn').className = 'pill'; loadState(); });
  es.addEventListener('error', () => { $('conn').textContent = 'reconnecting'; $('conn').className = 'pill off'; });
  es.addEventListener('message', onEvent);
  es.addEventListener('reset', () => loadState());
}

async function control(cmd, args) {
  const token = $('token').value.trim();
  const r = await fetch('/api/' + cmd, {
    method: 'POST', headers: {'Authorization': 'Bearer ' + token, 'Content-Type': 'application/json'},
    body: JSON.stringify(args),
  });
  const body = await r.json().catch(() => ({}));
  $('control-status').textContent = r.ok ? `${cmd}: job ${body.job} ${body.state}` :
    `${cmd} refused (${r.status}): ${body.error || ''}`;
  if (r.ok && cmd !== 'cancel') lastJob = body.job;
}

function reconArgs() {
  const a = {method: $('method').value, preset: $('preset').value};
  const b = parseFloat($('budget').value);
  if (isFinite(b) && b > 0) a.budget_s = b;
  return a;
}

function wireControl() {
  $('btn-capture').addEventListener('click', () => control('capture', {count: 1}));
  $('btn-capture-recon').addEventListener('click', () => {
    const a = reconArgs();
    const args = {count: 1, reconstruct: true, method: a.method, preset: a.preset};
    control('capture', args);
  });
  $('btn-recon').addEventListener('click', () => { if (latest) control('reconstruct', {capture: latest, ...reconArgs()}); });
  $('btn-cancel').addEventListener('click', () => { if (lastJob) control('cancel', {job: lastJob}); });
}

// The measured curves (bench/results.csv columns scene, method, setting, psnr_db, wall_s, ...): for each method and
// setting the mean PSNR and solver time over the scenes, one line per method, solver time on a log axis.
const PALETTE = ['#2f6fde', '#d9822b', '#2c9a5b', '#b03aa8', '#c23b3b', '#6b6f7a', '#1a9fb0', '#8a6d1f'];

async function loadCurves() {
  const r = await fetch('/api/curves');
  if (!r.ok) return;
  const lines = (await r.text()).trim().split('\n');
  const head = lines.shift().split(',');
  const col = (name) => head.indexOf(name);
  const [cm, cs, cp, cw] = [col('method'), col('setting'), col('psnr_db'), col('wall_s')];
  if (cm < 0 || cs < 0 || cp < 0 || cw < 0) return;
  const acc = new Map();
  for (const line of lines) {
    const f = line.split(',');
    const key = f[cm] + '\u0000' + f[cs];
    const a = acc.get(key) || {method: f[cm], setting: f[cs], psnr: 0, wall: 0, n: 0};
    a.psnr += parseFloat(f[cp]); a.wall += parseFloat(f[cw]); a.n++;
    acc.set(key, a);
  }
  const byMethod = new Map();
  for (const a of acc.values()) {
    if (!isFinite(a.psnr) || !isFinite(a.wall) || a.wall <= 0) continue;
    if (!byMethod.has(a.method)) byMethod.set(a.method, []);
    byMethod.get(a.method).push({x: a.wall / a.n, y: a.psnr / a.n, setting: a.setting});
  }
  const datasets = [...byMethod.entries()].map(([m, pts], i) => ({
    label: m, data: pts.sort((p, q) => p.x - q.x), borderColor: PALETTE[i % PALETTE.length],
    backgroundColor: PALETTE[i % PALETTE.length], pointRadius: 2.5, borderWidth: 1.5, showLine: true}));
  if (!datasets.length) return;
  $('curves-card').hidden = false;
  new Chart($('curves'), {
    type: 'scatter', data: {datasets},
    options: {
      animation: false, responsive: true, maintainAspectRatio: false, parsing: false,
      scales: {x: {type: 'logarithmic', title: {display: true, text: 'solver time (s, log)'}},
               y: {title: {display: true, text: 'PSNR (dB)'}}},
      plugins: {legend: {position: 'bottom', labels: {boxWidth: 12}},
                tooltip: {callbacks: {label: (c) => `${c.dataset.label} ${c.raw.setting}: ` +
                                                      `${fmt(c.raw.y, 2)} dB in ${fmt(c.raw.x, 3)} s`}}},
    },
  });
  document.body.dataset.curves = datasets.length;
}

document.addEventListener('DOMContentLoaded', () => {
  document.body.dataset.points = 0;
  wireControl();
  loadState();
  loadCurves();
  connect();
});
