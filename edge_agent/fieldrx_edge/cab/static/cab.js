// The cab screen: draws the job's own geometry (GET /api/job) and follows the agent's
// live state (Server-Sent Events on /events). Buttons POST /api/control to the same session.
'use strict';
const $ = (id) => document.getElementById(id);
const cab = { job: null, s: null, painted: new Set(), latency: [], alarmShown: {}, headingUp: true,
  paths: [], rmin: 0, rmax: 1, lastN: -1, events: 0, audio: null };
window.cab = cab;

function fmt(v, d = 1) { return v === null || v === undefined || Number.isNaN(v) ? '-' : Number(v).toFixed(d); }

async function control(body) {
  const r = await fetch('/api/control', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) });
  const j = await r.json();
  $('msg').textContent = r.ok ? '' : j.error;
  return j;
}

function rateColour(r) {
  if (!(r > 0)) return 'rgba(128,128,128,0.25)';
  const f = cab.rmax > cab.rmin ? (r - cab.rmin) / (cab.rmax - cab.rmin) : 0.5;
  // light yellow-green (low) to dark green (high)
  const h = 70 + 60 * f, l = 78 - 45 * f;
  return `hsl(${h},65%,${l}%)`;
}

async function loadJob() {
  const job = await (await fetch('/api/job')).json();
  cab.job = job;
  const rates = job.rate.filter((r) => r > 0);
  cab.rmin = rates.length ? Math.min(...rates) : 0;
  cab.rmax = rates.length ? Math.max(...rates) : 1;
  cab.index = new Map(job.seq.map((s, i) => [s, i]));
  cab.paths = job.cells.map((rings) => {
    const p = new Path2D();
    for (const r of rings) {
      p.moveTo(r[0], r[1]);
      for (let k = 2; k < r.length; k += 2) p.lineTo(r[k], r[k + 1]);
      p.closePath();
    }
    return p;
  });
  cab.boundary = new Path2D();
  for (const r of job.boundary) {
    cab.boundary.moveTo(r[0], r[1]);
    for (let k = 2; k < r.length; k += 2) cab.boundary.lineTo(r[k], r[k + 1]);
    cab.boundary.closePath();
  }
  // a seeding job meters nothing: its depth figures take the rate tiles' place
  document.body.classList.toggle('no-rate', !job.view.shows_rate);
  // the sensor kinds' loops take no operator hand (pause, override, sections) yet
  document.body.classList.toggle('no-hand', !job.view.hand_overrides);
  $('job').textContent = `Job ${job.job_id} · ${job.field} · ${job.product || job.kind}`;
  $('legend').textContent = job.view.rates_from === 'cells' ? `${fmt(cab.rmin, 0)}-${fmt(cab.rmax, 0)} kg/ha · blue: applied` : `${job.kind} · blue: worked`;
  const n = job.view.hand_overrides ? (cab.s?.operator?.sections || 1) : 0;
  buildSections(n);
}

function buildSections(n) {
  const box = $('sections');
  box.textContent = '';
  for (let k = 0; k < n; k++) {
    const b = document.createElement('button');
    b.textContent = `S${k + 1}`;
    b.dataset.testid = `cab-section-${k}`;
    b.setAttribute('data-testid', `cab-section-${k}`);
    b.onclick = () => control({ action: 'section', section: k });
    box.appendChild(b);
  }
}

function draw() {
  const cv = $('map');
  const w = cv.clientWidth, h = cv.clientHeight;
  if (cv.width !== w * devicePixelRatio) { cv.width = w * devicePixelRatio; cv.height = h * devicePixelRatio; }
  const ctx = cv.getContext('2d');
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.clearRect(0, 0, cv.width, cv.height);
  const job = cab.job, s = cab.s;
  if (!job) return;
  const night = document.body.classList.contains('night');
  const pos = s?.pos || [0, 0];
  const heading = (s?.rec?.heading_deg || 0) * Math.PI / 180;
  const scale = devicePixelRatio * Math.min(w, h) / 90; // about 90 m across the short side
  ctx.translate(cv.width / 2, cv.height * 0.62);
  if (cab.headingUp) ctx.rotate(-heading);
  ctx.scale(scale, -scale);
  ctx.translate(-pos[0], -pos[1]);
  ctx.lineWidth = 1 / scale * devicePixelRatio;
  for (let i = 0; i < cab.paths.length; i++) {
    ctx.fillStyle = rateColour(job.rate[i]);
    ctx.fill(cab.paths[i]);
    if (cab.painted.has(job.seq[i])) { ctx.fillStyle = 'rgba(11,87,208,0.55)'; ctx.fill(cab.paths[i]); }
    ctx.strokeStyle = night ? 'rgba(255,255,255,0.15)' : 'rgba(0,0,0,0.15)';
    ctx.stroke(cab.paths[i]);
  }
  ctx.lineWidth = 3 / scale * devicePixelRatio;
  ctx.strokeStyle = night ? '#fff' : '#000';
  ctx.stroke(cab.boundary);
  // planned path: every swath line dashed, the current one solid, the next turn marked
  const g = s?.guidance;
  for (const [sw, l] of Object.entries(job.lines)) {
    ctx.beginPath(); ctx.moveTo(l[0], l[1]); ctx.lineTo(l[2], l[3]);
    const cur = g && String(g.swath) === sw;
    ctx.setLineDash(cur ? [] : [2, 2]);
    ctx.strokeStyle = cur ? '#ff00aa' : 'rgba(255,0,170,0.35)';
    ctx.lineWidth = (cur ? 4 : 1.5) / scale * devicePixelRatio;
    ctx.stroke();
  }
  ctx.setLineDash([]);
  if (g?.turn_at) { ctx.beginPath(); ctx.arc(g.turn_at[0], g.turn_at[1], 1.5, 0, 7); ctx.fillStyle = '#ff00aa'; ctx.fill(); }
  const cell = s?.rec?.cell_seq;
  if (cell !== null && cell !== undefined && cab.index.has(cell)) {
    ctx.lineWidth = 5 / scale * devicePixelRatio; ctx.strokeStyle = '#ffd400';
    ctx.stroke(cab.paths[cab.index.get(cell)]);
  }
  // the tractor and its implement's sections
  ctx.save(); ctx.translate(pos[0], pos[1]); ctx.rotate(-heading);
  const half = job.width_m / 2, op = s?.operator || { sections: 1, sections_off: [], paused: false };
  const n = op.sections || 1, metering = (s?.rec?.target_shaft_rpm || 0) > 0 && !op.paused;
  for (let k = 0; k < n; k++) {
    const off = op.sections_off.includes(k);
    ctx.fillStyle = off || !metering ? '#888' : '#1b8a2f';
    ctx.fillRect(-half + (k * job.width_m) / n, -1.2, job.width_m / n - 0.1, 0.8);
  }
  ctx.beginPath(); ctx.moveTo(0, 3); ctx.lineTo(-1.3, -0.5); ctx.lineTo(1.3, -0.5); ctx.closePath();
  ctx.fillStyle = '#d00'; ctx.fill(); ctx.restore();
}

function gauge(okId, markId, lo, hi, v, min, max) {
  const span = max - min || 1, pct = (x) => `${Math.max(0, Math.min(100, ((x - min) / span) * 100))}%`;
  $(okId).style.left = pct(lo); $(okId).style.width = `calc(${pct(hi)} - ${pct(lo)})`;
  $(markId).style.left = pct(v ?? min);
}

function lightbar(g) {
  const leds = $('leds');
  if (!leds.children.length) for (let k = 0; k < 15; k++) leds.appendChild(document.createElement('i'));
  const xte = g ? g.xte_m : 0, k = Math.max(-7, Math.min(7, Math.round(-xte / 0.1)));
  [...leds.children].forEach((el, i) => {
    const d = i - 7; el.className = (d === 0 ? 'c' : d < 0 ? 'l' : 'r') + ((d === 0 && k === 0) || (d !== 0 && Math.sign(d) === Math.sign(k) && Math.abs(d) <= Math.abs(k)) ? ' on' : '');
  });
  $('steer').textContent = g ? (g.steer === 'on line' ? 'On line' : `Steer ${g.steer} ${fmt(Math.abs(xte) * 100, 0)} cm`) : '-';
  $('turn').textContent = g ? `Turn in ${fmt(g.to_turn_m, 0)} m` : '-';
}

function beep() {
  try {
    cab.audio = cab.audio || new AudioContext();
    const o = cab.audio.createOscillator(), gn = cab.audio.createGain();
    o.frequency.value = 880; gn.gain.value = 0.2; o.connect(gn).connect(cab.audio.destination);
    o.start(); o.stop(cab.audio.currentTime + 0.35);
  } catch (e) { /* no audio device: the banner still shows */ }
}

function alarms(list) {
  const open = list.filter((a) => !a.acked);
  const now = Date.now() / 1000;
  for (const a of open) {
    if (!cab.alarmShown[a.name] || cab.alarmShown[a.name].first !== a.first_wall) {
      cab.alarmShown[a.name] = { first: a.first_wall, shown: now };
      beep();
    }
  }
  const box = $('alarm');
  box.hidden = list.length === 0;
  box.classList.toggle('acked', open.length === 0);
  box.dataset.names = list.map((a) => a.name).join(' ');
  $('alarmtext').textContent = list.map((a) => a.label + (a.active ? '' : ' (over)') + (a.acked ? ' ✓' : '')).join(' · ');
  $('ack').hidden = open.length === 0;
}

function kindPanel(s) {
  const r = s.rec, box = $('kind');
  if (!cab.job || !cab.job.view.panel) { box.textContent = ''; return; }
  if (cab.job.view.panel === 'ndvi') {
    box.innerHTML = `<div class="tile"><label>NDVI raw / filtered</label><b data-testid="cab-ndvi">${fmt(r.ndvi_raw, 3)} / ${fmt(r.ndvi, 3)}</b></div>
      <div class="tile"><label>Rate curve point</label><b data-testid="cab-curve">${fmt(r.ndvi, 2)} → ${fmt(r.target_rate_kg_ha, 0)} kg/ha</b></div>`;
  } else {
    const d = s.depth || {}, v = (r.speed_filtered_m_s || 0) * 3.6;
    const bands = (cab.job.kind_settings.speed_bands_kmh || []).map((b) => `${b[0]}-${b[1]}`).join(' / ');
    const band = (cab.job.kind_settings.speed_bands_kmh || []).find((b) => v >= b[0] && v <= b[1]);
    box.innerHTML = `<div class="tile"><label>Depth / target mm</label><b data-testid="cab-depth">${fmt(r.depth_mm, 1)} / ${fmt(d.target_mm, 0)}</b></div>
      <div class="tile"><label>Qualified, last ${fmt(d.window_m, 0)} m</label><b data-testid="cab-qualified">${fmt(d.qualified_pct, 1)} %</b></div>
      <div class="tile"><label>Actuator mm</label><b data-testid="cab-actuator">${fmt(r.actuator_mm, 1)}</b></div>
      <div class="tile"><label>Speed band (${bands} km/h)</label><b data-testid="cab-band">${band ? `${band[0]}-${band[1]}` : 'outside'} @ ${fmt(v, 1)}</b></div>`;
  }
}

function show(s) {
  const prev = cab.s;
  cab.s = s;
  cab.events += 1;
  if (s.n !== cab.lastN && s.rec_wall) { cab.latency.push(Date.now() / 1000 - s.rec_wall); cab.lastN = s.n; }
  for (const c of s.new_cells) cab.painted.add(c);
  const r = s.rec || {};
  $('state').textContent = s.state; $('state').className = 'pill ' + (s.state === 'running' ? 'ok' : 'warn');
  $('cell').textContent = r.cell_seq ?? '-';
  $('target').textContent = fmt(r.target_rate_kg_ha, 1);
  $('actual').textContent = fmt(r.applied_rate_kg_ha, 1);
  const dev = r.target_rate_kg_ha > 0 && r.applied_rate_kg_ha !== undefined ? (100 * (r.applied_rate_kg_ha - r.target_rate_kg_ha)) / r.target_rate_kg_ha : null;
  $('dev').textContent = dev === null ? '-' : `${dev > 0 ? '+' : ''}${fmt(dev, 1)} %`;
  const v = (r.speed_filtered_m_s || 0) * 3.6, band = s.speed_band_m_s.map((x) => x * 3.6);
  $('speed').textContent = fmt(v, 1); $('band').textContent = `${fmt(band[0], 1)}-${fmt(band[1], 1)}`;
  gauge('speedok', 'speedmark', band[0], band[1], v, 0, band[1] * 1.5);
  $('rpm').textContent = `${fmt(r.actual_shaft_rpm, 1)} / ${fmt(r.target_shaft_rpm, 1)}`;
  $('rpmrange').textContent = `${fmt(s.meter_rpm[0], 0)}-${fmt(s.meter_rpm[1], 0)}`;
  gauge('rpmok', 'rpmmark', s.meter_rpm[0], s.meter_rpm[1], r.actual_shaft_rpm, 0, s.meter_rpm[1] * 1.25);
  $('done').textContent = fmt(s.area.done_ha, 3); $('left').textContent = fmt(s.area.left_ha, 3);
  $('applied').textContent = fmt(s.product.applied_kg, 1);
  $('tank').textContent = s.product.left_kg !== undefined ? `${fmt(s.product.left_kg, 0)} (${fmt(s.product.lasts_m, 0)} m)` : 'set';
  const fix = { 0: 'no fix', 1: 'GPS', 2: 'DGPS', 4: 'RTK fix', 5: 'RTK float' }[r.fix_quality] || `q${r.fix_quality}`;
  $('gnss').textContent = `${fix} · sats ${r.sats ?? '-'} · HDOP ${fmt(r.hdop, 1)} · ${fmt(s.age_s, 1)} s`;
  $('gnss').className = 'pill ' + (r.fix_quality === 0 ? 'bad' : r.fix_quality === 4 ? 'ok' : 'warn');
  $('uplink').textContent = `uplink ${s.uplink.state} · ${s.uplink.backlog} queued`;
  $('uplink').className = 'pill ' + ({ online: 'ok', offline: 'warn', connecting: 'warn', unreachable: 'bad' }[s.uplink.state] || '');
  const op = s.operator;
  $('override').textContent = `${op.override_pct > 0 ? '+' : ''}${op.override_pct} %${op.limited ? ' (meter limit)' : ''}`;
  $('override').classList.toggle('limited', op.limited);
  $('pause').hidden = op.paused || s.state === 'ready'; $('resume').hidden = !op.paused; $('start').hidden = s.state !== 'ready';
  if (!prev || prev.operator.sections !== op.sections) buildSections(cab.job && cab.job.view.hand_overrides ? op.sections : 0);
  [...$('sections').children].forEach((b, k) => { b.style.opacity = op.sections_off.includes(k) ? 0.4 : 1; });
  lightbar(s.guidance);
  alarms(s.alarms);
  kindPanel(s);
  if (s.summary && $('summary').hidden && !cab.summaryClosed) {
    const show1 = (v) => (typeof v === 'number' ? (Number.isInteger(v) ? String(v) : fmt(v, 3))
      : Array.isArray(v) ? (v.join(', ') || 'none') : v && typeof v === 'object' ? `${v.state}, ${v.backlog} queued` : String(v));
    $('sumlist').innerHTML = Object.entries(s.summary).map(([k, v]) => `<dt>${k.replaceAll('_', ' ')}</dt><dd>${show1(v)}</dd>`).join('');
    $('summary').hidden = false;
  }
  requestAnimationFrame(draw);
}

async function showJobs() {
  const rows = await (await fetch('/api/jobs')).json();
  $('jobrows').innerHTML = rows.map((j) => `<tr data-testid="cab-jobrow-${j.job_id}"><td>${j.job_id}</td><td>${j.kind ?? ''}</td><td>${j.field ?? ''}</td><td>${j.product ?? ''}</td><td>${j.prescription_version ?? ''}</td><td>${j.planned_kg ?? '-'}</td><td>${j.area_ha ?? ''}</td><td>${j.machine_check ?? j.error}</td><td>${j.state ?? ''}</td></tr>`).join('');
  $('jobs').hidden = false;
}

function wire() {
  $('pause').onclick = () => control({ action: 'pause' });
  $('resume').onclick = () => control({ action: 'resume' });
  $('start').onclick = () => control({ action: 'start' });
  $('finish').onclick = () => control({ action: 'finish' });
  $('plus').onclick = () => control({ action: 'override', steps: 1 });
  $('minus').onclick = () => control({ action: 'override', steps: -1 });
  $('ack').onclick = () => control({ action: 'ack' });
  $('close').onclick = () => { cab.summaryClosed = true; $('summary').hidden = true; control({ action: 'close' }); };
  $('jobsbtn').onclick = showJobs;
  $('pull').onclick = async () => { const r = await control({ action: 'pull' }); if (r.pulled) { $('msg').textContent = `pulled ${JSON.stringify(r.pulled)}`; showJobs(); } };
  $('jobsclose').onclick = () => { $('jobs').hidden = true; };
  $('orient').onclick = () => { cab.headingUp = !cab.headingUp; $('orient').textContent = cab.headingUp ? 'Heading up' : 'North up'; requestAnimationFrame(draw); };
  $('theme').onclick = () => { const n = document.body.classList.toggle('night'); document.body.classList.toggle('day', !n); $('theme').textContent = n ? 'Day' : 'Night'; requestAnimationFrame(draw); };
  $('tank').parentElement.onclick = () => { const kg = Number(prompt('Tank mass at start (kg)')); if (kg) control({ action: 'tank', kg }); };
  window.addEventListener('resize', () => requestAnimationFrame(draw));
}

async function main() {
  wire();
  await loadJob();
  const es = new EventSource('/events');
  es.onmessage = (e) => show(JSON.parse(e.data));
  es.onerror = () => { $('state').textContent = 'agent not answering'; $('state').className = 'pill bad'; };
}
main();
