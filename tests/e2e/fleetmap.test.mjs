// The live fleet map as a view of the same truth as the list and the report: a job is
// driven by `fieldrx-edge simulate --server` (at 10x real time, so the screen is sampled along the drive) while the fleet screen is open. At every sample
// the machine's marker has the colour of the state the list beside it shows, and its name
// label sits on the marker; at the end the painted coverage is exactly the report's applied
// cells. Set-up through the API; the fleet screen is what is tested.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import { existsSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, ROOT, api, apiLogin, launch, mapIdle, serverUp, shot, signIn, sleep, uiServed, scaled } from './lib.mjs';

const up = await serverUp();
const ui = up && (await uiServed());
const EDGE = join(ROOT, '.venv', 'bin', 'fieldrx-edge');
const SKIP = !up ? `no server at ${BASE_URL}` : !ui ? 'server does not serve the UI' : !existsSync(EDGE) ? 'no fieldrx-edge' : false;

const PLOT = {
  type: 'Polygon',
  coordinates: [[[112.53, 32.34], [112.53045, 32.34], [112.53045, 32.34025], [112.53, 32.34025], [112.53, 32.34]]],
};

/**
 * One reading of the screen: the list's state and dot, the marker as drawn (colour, where),
 * the label's distance from it. Taken three animation frames after reading the list (the
 * map's source follows the list's render in an effect, its worker a frame later); `settled`
 * is false when the list changed meanwhile (that reading is dropped).
 */
function sample(id) {
  const stateNow = () => document.querySelector(`[data-testid=machine-status-${id}]`)?.textContent?.trim() ?? null;
  const before = stateNow();
  const map = window.__fieldrxMaps.fleet;
  const frame = () => new Promise((r) => requestAnimationFrame(() => r()));
  // not the map's idle event: under a busy live feed it may not come for the whole drive
  return frame()
    .then(frame)
    .then(frame)
    .then(() => {
      const state = stateNow();
      const dot = document.querySelector(`[data-testid=fleet-machine-${id}] .dot`);
      const legend = [...document.querySelectorAll('[data-testid=fleet-legend] > span')].find((s) => s.textContent.trim() === state);
      const feat = map.queryRenderedFeatures({ layers: ['machines-dot'] }).find((f) => Number(f.properties?.machine_id) === id);
      const norm = (c) => {
        const el = document.createElement('span');
        el.style.color = c;
        document.body.appendChild(el);
        const v = getComputedStyle(el).color;
        el.remove();
        return v;
      };
      let labelPx = null;
      const label = document.querySelector(`[data-testid=map-label-${id}]`);
      if (feat && label) {
        const r = label.getBoundingClientRect();
        const c = map.getCanvas().getBoundingClientRect();
        const p = map.project(feat.geometry.coordinates);
        labelPx = Math.hypot(r.left + r.width / 2 - (c.left + p.x), r.top + r.height / 2 - (c.top + p.y));
      }
      return {
        settled: state === before,
        state,
        list: dot ? norm(getComputedStyle(dot).backgroundColor) : null,
        legend: legend ? norm(getComputedStyle(legend.querySelector('.dot')).backgroundColor) : null,
        marker: feat ? norm(feat.properties.color) : null,
        labelPx,
      };
    });
}

/** The cells the fleet map paints as covered (the coverage layer's own filter, over the loaded tiles). */
function painted(jobId) {
  const map = window.__fieldrxMaps.fleet;
  const id = `coverage-${jobId}`;
  if (!map.getSource(id) || !map.isSourceLoaded(id)) return null;
  const layer = map.getLayer(`${id}-fill`);
  const color = map.getPaintProperty(`${id}-fill`, 'fill-color');
  if (!layer || !Array.isArray(color) || color[0] !== 'case') return null;
  const seqs = new Set(map.querySourceFeatures(id, { sourceLayer: 'cells', filter: color[1] }).map((f) => Number(f.properties.seq)));
  return [...seqs].sort((a, b) => a - b);
}

describe('fleet map: marker, label and coverage agree with the list and the report', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  let job;
  let machine;
  before(async () => {
    token = await apiLogin();
    const f = await api(token, 'POST', '/fields', { type: 'Feature', properties: { name: 'fleet map plot' }, geometry: PLOT });
    assert.ok(f.ok, `field ${f.status}`);
    const calibration = { kind: 'linear', slope_g_min_per_rpm: 237.2, intercept_g_min: -404.4, min_rpm: 5, max_rpm: 130 };
    const m = await api(token, 'POST', '/machines', { name: `fleet map spreader ${Date.now()}`, width_m: 3.6, lag_s: 1.52, calibration });
    assert.ok(m.ok, `machine ${m.status} ${JSON.stringify(m.data)}`);
    machine = m.data;
    const p = await api(token, 'POST', `/fields/${f.data.id}/plans`, { swath_width_m: 3.6, cell_length_m: 5, headland_passes: 0 });
    assert.ok(p.ok, `plan ${p.status}`);
    const rx = await api(token, 'POST', `/plans/${p.data.id}/prescriptions`, {
      model: 'uniform',
      params: { rate_kg_ha: 150 },
      product: 'Urea 46 % N',
      name: 'fleet map rx',
    });
    assert.ok(rx.ok, `prescription ${rx.status} ${JSON.stringify(rx.data)}`);
    const j = await api(token, 'POST', '/jobs', { prescription_id: rx.data.id, machine_id: machine.id, confirm_flagged: true });
    assert.ok(j.ok, `job ${j.status} ${JSON.stringify(j.data)}`);
    job = j.data;
    assert.ok((await api(token, 'POST', `/jobs/${job.id}/state`, { state: 'sent' })).ok);
    // Two machines parked 30 and 900 km away, seen before the screen opens: the map is fitted
    // to them (zoomed out, where the job's cells are smaller than a pixel), so the driven
    // machine and its coverage are seen only by following it from the list.
    for (const [i, [lon, lat]] of [[112.32, 32.13], [116.4, 39.9]].entries()) {
      const far = await api(token, 'POST', '/machines', { name: `fleet map parked ${i} ${Date.now()}`, width_m: 3.6, lag_s: 1.52, calibration });
      assert.ok(far.ok, `machine ${far.status}`);
      const farToken = await api(token, 'POST', `/machines/${far.data.id}/device-token`);
      const parked = {
        machine_id: far.data.id, seq: 1, t: Date.now() / 1000, lon, lat, fix_quality: 4, hdop: 0.8,
        speed_raw_m_s: 0, speed_filtered_m_s: 0, heading_deg: 0, job_id: null, cell_seq: null,
        target_rate_kg_ha: 0, applied_rate_kg_ha: 0, target_shaft_rpm: 0, actual_shaft_rpm: 0, duty: 0,
        implement_down: false, alarms: [], queue_backlog: 0,
      };
      const r = await api(farToken.data.token, 'POST', '/telemetry', { records: [parked] });
      assert.ok(r.ok, `telemetry ${r.status} ${JSON.stringify(r.data)}`);
    }
    B = await launch();
    page = B.page;
    await signIn(page);
  });
  after(async () => {
    if (B) {
      writeFileSync(join(ARTIFACTS, 'fleetmap-browser-console.log'), B.logs.join('\n'));
      await B.close();
    }
  });

  it('watches a simulated job: marker colour = list state, label on marker, coverage = report', async () => {
    const dt = await api(token, 'POST', `/machines/${machine.id}/device-token`);
    assert.ok(dt.ok, `device token ${dt.status}`);
    const res = await fetch(`${BASE_URL}/api/v1/device/jobs/${job.id}/package`, { headers: { Authorization: `Bearer ${dt.data.token}` } });
    assert.ok(res.ok, `package ${res.status}`);
    const file = join(ARTIFACTS, `fleetmap-job-${job.id}.json`);
    writeFileSync(file, Buffer.from(await res.arrayBuffer()));
    await page.goto(`${BASE_URL}/#/fleet`);
    await mapIdle(page, 'fleet');
    await page.waitForSelector('[data-testid=live-state]:has-text("open")', { timeout: scaled(30_000) });
    // The jobs list in a second tab, its polls failing from now on (a stale list): only the
    // live feed can move the job's row on.
    const jobsPage = await B.context.newPage();
    await signIn(jobsPage);
    await jobsPage.goto(`${BASE_URL}/#/jobs`);
    await jobsPage.waitForSelector(`[data-testid=job-state-${job.id}]`);
    const stateBefore = await jobsPage.textContent(`[data-testid=job-state-${job.id}]`);
    assert.notEqual(stateBefore.trim(), 'completed');
    await jobsPage.route('**/api/v1/jobs?*', (r) => r.abort());
    await jobsPage.route('**/api/v1/jobs', (r) => r.abort());
    const sim = spawn(EDGE, ['simulate', file, '--server', BASE_URL, '--token', dt.data.token, '--json', '--realtime', '10'], { stdio: ['ignore', 'pipe', 'pipe'] });
    let simOut = '';
    sim.stdout.on('data', (d) => (simOut += d));
    sim.stderr.on('data', (d) => (simOut += d));
    const exited = new Promise((r) => sim.on('exit', r));
    const samples = [];
    try {
      let done = false;
      void exited.then(() => (done = true));
      const deadline = Date.now() + scaled(300_000);
      let following = false;
      while (!done && Date.now() < deadline) {
        // The map was fitted to the machines already on it (earlier tests' may be far away):
        // follow this one from the list as soon as it has a position, as a user would.
        if (!following) {
          const follow = page.locator(`[data-testid=fleet-follow-${machine.id}]`);
          if ((await follow.count()) > 0) {
            await follow.click();
            following = (await follow.getAttribute('aria-pressed')) === 'true';
          }
        }
        const s = await page.evaluate(sample, machine.id);
        if (s.marker != null && s.settled) samples.push(s);
        await sleep(300);
      }
      assert.ok(done, 'simulator finished');
      assert.equal(sim.exitCode, 0, 'simulator exit code (see artifacts/fleetmap-simulate.log)');
    } finally {
      if (sim.exitCode == null) sim.kill('SIGTERM');
      writeFileSync(join(ARTIFACTS, 'fleetmap-simulate.log'), simOut);
      writeFileSync(join(ARTIFACTS, 'fleetmap-samples.json'), JSON.stringify(samples, null, 1));
    }
    await shot(page, 'fleetmap-end');
    assert.ok(samples.length >= 3, `the machine was on the map while driving (${samples.length} samples)`);
    assert.equal(await page.getAttribute(`[data-testid=fleet-follow-${machine.id}]`, 'aria-pressed'), 'true', 'the list shows the machine followed');
    assert.ok(samples.some((s) => s.state === 'working'), `seen working: ${[...new Set(samples.map((s) => s.state))]}`);
    for (const [i, s] of samples.entries()) {
      assert.equal(s.marker, s.list, `sample ${i}: marker colour ${s.marker} vs list dot ${s.list} (${s.state})`);
      assert.equal(s.list, s.legend, `sample ${i}: list dot ${s.list} is the legend's colour for "${s.state}"`);
      assert.ok(s.labelPx != null && s.labelPx <= 40, `sample ${i}: label ${s.labelPx} px from its marker`);
    }

    // The end: the job is over, and the coverage painted is the report's applied cells.
    const deadline = Date.now() + scaled(120_000);
    let st;
    do {
      st = (await api(token, 'GET', `/jobs/${job.id}`)).data?.state;
      if (st === 'completed') break;
      await sleep(1000);
    } while (Date.now() < deadline);
    assert.equal(st, 'completed', 'job completed');
    await jobsPage.waitForSelector(`[data-testid=job-state-${job.id}]:has-text("completed")`, { timeout: scaled(30_000) });
    const jobNow = (await api(token, 'GET', `/jobs/${job.id}`)).data;
    const shownPct = parseFloat(await jobsPage.textContent(`[data-testid=job-progress-${job.id}]`));
    assert.ok(Math.abs(shownPct - jobNow.progress * 100) < 0.06, `the stale list shows the feed's progress: ${shownPct} vs ${jobNow.progress}`);
    await shot(jobsPage, 'fleetmap-jobs-list-live');
    const rep = await api(token, 'GET', `/jobs/${job.id}/as-applied/cells`);
    assert.ok(rep.ok, `report cells ${rep.status}`);
    const applied = rep.data.features
      .filter((f) => f.properties.target_rate_kg_ha > 0 && f.properties.m2_g > 0)
      .map((f) => Number(f.properties.seq))
      .sort((a, b) => a - b);
    assert.equal(applied.length, rep.data.summary.cells_applied, "the report's applied cells");
    assert.ok(applied.length > 0, 'cells applied');
    // the map re-requests coverage when the job's state changes: wait for that, not a fixed time
    let shown = null;
    const until = Date.now() + scaled(60_000);
    while (Date.now() < until) {
      await mapIdle(page, 'fleet');
      shown = await page.evaluate(painted, job.id);
      if (shown && shown.length === applied.length && shown.every((q, i) => q === applied[i])) break;
      await sleep(1000);
    }
    await shot(page, 'fleetmap-coverage');
    assert.deepEqual(shown, applied, 'painted coverage = report applied cells');
  });
});
