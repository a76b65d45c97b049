// feedloop's page: polls the API once a second and keeps every tracking-error point it has seen.
'use strict';
const pts = { t: [], x: [], y: [], z: [], e: [] };
let next = 0;
let timePlot = null, mapPlot = null;
const layerSelect = document.getElementById('layer');
let chosenLayer = null;  // null: the latest

async function rpc(method, params) {
  const r = await fetch('/' + method.replaceAll('.', '/') + '?' + new URLSearchParams(params || {}));
  if (!r.ok) throw new Error(method + ': HTTP ' + r.status);
  return (await r.json()).result;
}

function colorFor(e, max) {
  const f = max > 0 ? Math.min(1, e / max) : 0;  // blue (small) .. red (large)
  return `rgb(${Math.round(255 * f)},${Math.round(80 * (1 - f))},${Math.round(255 * (1 - f))})`;
}

function drawTime() {
  const data = [pts.t, pts.e.map((v) => v * 1000)];
  if (!timePlot) {
    timePlot = new uPlot({ width: 560, height: 320, scales: { x: { time: false } },
      axes: [{ label: 't (s)' }, { label: 'e_t (µm)' }],
      series: [{ label: 't (s)' }, { label: 'mean |e_t| (µm)', stroke: '#c03', width: 1 }] }, data,
      document.getElementById('time-plot'));
  } else timePlot.setData(data);
}

function drawMap(layerZ) {
  const xs = [], ys = [], es = [];
  for (let i = 0; i < pts.t.length; i++)
    if (Math.abs(pts.z[i] - layerZ) < 1e-6) { xs.push(pts.x[i]); ys.push(pts.y[i]); es.push(pts.e[i]); }
  const maxE = es.reduce((a, b) => Math.max(a, b), 0);
  // One point per sample, coloured by its error: a scatter drawn by a custom path builder.
  const order = xs.map((_, i) => i).sort((a, b) => xs[a] - xs[b]);
  const data = [order.map((i) => xs[i]), order.map((i) => ys[i])];
  const colours = order.map((i) => colorFor(es[i], maxE));
  const scatter = (u, seriesIdx) => {
    uPlot.orient(u, seriesIdx, (series, dataX, dataY, scaleX, scaleY, valToPosX, valToPosY, xOff, yOff, xDim, yDim) => {
      const ctx = u.ctx;
      for (let i = 0; i < dataX.length; i++) {
        ctx.fillStyle = colours[i];
        const px = valToPosX(dataX[i], scaleX, xDim, xOff), py = valToPosY(dataY[i], scaleY, yDim, yOff);
        ctx.fillRect(px - 2, py - 2, 4, 4);
      }
    });
    return null;
  };
  if (mapPlot) mapPlot.destroy();
  mapPlot = new uPlot({ width: 420, height: 420, mode: 1, scales: { x: { time: false } },
    axes: [{ label: 'X (mm)' }, { label: 'Y (mm)' }],
    series: [{ label: 'X' }, { label: `e_t at Z=${layerZ} mm (max ${(maxE * 1000).toFixed(1)} µm)`, paths: scatter,
      points: { show: false }, stroke: '#c03' }] }, data, document.getElementById('map-plot'));
}

function updateTables(status) {
  const tr = status.feedloop_tracking, sv = status.feedloop_servo, links = status.feedloop_links.links;
  const tbody = document.querySelector('#layers tbody');
  tbody.innerHTML = tr.layers.map((l) => `<tr><td>${l.z_mm.toFixed(2)}</td><td>${(l.mean_mm * 1000).toFixed(2)}</td>` +
    `<td>${(l.max_mm * 1000).toFixed(2)}</td><td>${l.points}</td></tr>`).join('');
  const rows = [['servo period (ms)', (sv.period_s * 1000).toFixed(3)], ['cycles', sv.cycles],
    ['deadline misses', sv.deadline_misses], ['wake-up latency p50/p99/max (µs)',
      `${sv.latency_us.p50.toFixed(0)} / ${sv.latency_us.p99.toFixed(0)} / ${sv.latency_us.max.toFixed(0)}`],
    ['e_t now (µm)', (tr.error_now_mm * 1000).toFixed(2)], ['e_t max (µm)', (tr.error_max_mm * 1000).toFixed(2)],
    ['lost-step events', tr.lost_step_events]];
  for (const [name, l] of Object.entries(links))
    rows.push([`link ${name}`, `${l.state}, ${l.frames_sent} sent, ${l.retransmitted} resent, ${l.crc_errors} CRC errors`]);
  document.getElementById('servo').innerHTML = rows.map(([k, v]) => `<tr><th>${k}</th><td>${v}</td></tr>`).join('');
  const zs = tr.layers.map((l) => l.z_mm);
  const current = layerSelect.value;
  layerSelect.innerHTML = zs.map((z) => `<option value="${z}">${z.toFixed(2)} mm</option>`).join('');
  if (chosenLayer !== null) layerSelect.value = current;
  else if (zs.length) {  // the layer with the most points until one is chosen
    const best = tr.layers.reduce((a, l) => (l.points > a.points ? l : a), tr.layers[0]);
    layerSelect.value = String(best.z_mm);
  }
}

// The last calibration report (`feedloop ident fit --out DIR`, report.json: the DESIGN.md contract):
// the axis, the baseline and augmented models with their RMS, the effects found with their
// parameters, and report.md. Asked for again every 10 s (a new fit shows without a reload).
const esc = (s) => String(s).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c]))
const num = (v, d = 2) => (typeof v === 'number' ? v.toFixed(d) : esc(v ?? '–'));
let lastCalibration = '';
async function loadCalibration() {
  const body = document.getElementById('calibration-body');
  try {
    const c = await rpc('server.feedloop.calibration_report');
    const key = c.found ? `${c.path}@${c.modified}` : `none:${c.message}`;
    if (key === lastCalibration) return;
    lastCalibration = key;
    if (!c.found) {
      body.innerHTML = `<p class="muted">${esc(c.message)}</p>`;
      document.body.dataset.calibration = 'none';
      return;
    }
    const r = c.report, b = r.baseline || {}, a = r.augmented || {}, effects = Array.isArray(r.effects) ? r.effects : [];
    const when = new Date(c.modified * 1000).toISOString().replace('T', ' ').slice(0, 19) + ' UTC';
    const fx = effects.length
      ? effects.map((e) => `<tr><th>${esc(e.name)}</th><td>${Object.entries(e.params || {}).map(([k, v]) => `${esc(k)} = ${num(v, 4)}`).join(', ')}</td></tr>`).join('')
      : '<tr><td colspan="2" class="muted">none: the baseline model explains the data</td></tr>';
    body.innerHTML = `<p class="muted">${esc(c.path)}, ${when}</p>` +
      `<table><tr><th>axis</th><td>${esc(r.axis ?? '–')}</td></tr>` +
      `<tr><th>baseline</th><td>${esc(b.model ?? '–')}: RMS ${num(b.rms_um)} µm</td></tr>` +
      `<tr><th>augmented</th><td>${esc(a.model ?? '–')}: RMS ${num(a.rms_um)} µm</td></tr></table>` +
      `<h3>Effects found</h3><table id="calibration-effects">${fx}</table>` +
      (c.markdown ? `<details><summary>report.md</summary><pre>${esc(c.markdown)}</pre></details>` : '');
    document.body.dataset.calibration = 'shown';
    document.body.dataset.calibrationEffects = String(effects.length);
  } catch (err) {
    body.textContent = 'error: ' + err.message;
  }
}
loadCalibration();
setInterval(loadCalibration, 10000);

layerSelect.addEventListener('change', () => { chosenLayer = Number(layerSelect.value); drawMap(chosenLayer); });

async function poll() {
  try {
    for (;;) {
      const p = await rpc('server.feedloop.tracking_points', { from: next, limit: 20000 });
      pts.t.push(...p.t_s); pts.x.push(...p.x_mm); pts.y.push(...p.y_mm); pts.z.push(...p.z_mm); pts.e.push(...p.error_mm);
      const got = p.next - next;
      next = p.next;
      if (got < 20000) break;
    }
    const q = await rpc('printer.objects.query', { feedloop_tracking: '', feedloop_servo: '', feedloop_links: '', print_stats: 'state,filename' });
    updateTables(q.status);
    document.getElementById('status').textContent = `${pts.t.length} points, print: ${q.status.print_stats.state}` +
      (q.status.print_stats.filename ? ` (${q.status.print_stats.filename})` : '');
    drawTime();
    if (layerSelect.value !== '') drawMap(Number(layerSelect.value));
    document.body.dataset.points = String(pts.t.length);
  } catch (err) {
    document.getElementById('status').textContent = 'error: ' + err.message;
  }
  setTimeout(poll, 1000);
}
poll();
