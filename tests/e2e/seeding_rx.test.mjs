// Variable-rate seeding in the browser: a seeds/ha prescription from the samples' NDVI with
// a seed lot's TKW and germination typed in the form, the screen showing the unit, the lot
// and the mean in seeds/ha, and a seeding job sent to a drill from the prescription screen
// (the only kind that takes seeds/ha). Set-up (field, samples, plan, drill) through the API;
// checked against the API's figures.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, ROOT, api, apiLogin, launch, run, scaled, serverUp, shot, signIn, uiServed } from './lib.mjs';

const EDGE = join(ROOT, '.venv', 'bin', 'fieldrx-edge');

const up = await serverUp();
const ui = up && (await uiServed());
const SKIP = !up ? `no server at ${BASE_URL}` : !ui ? 'server does not serve the UI' : false;

const LON0 = 112.45;
const LAT0 = 32.26;
const DLON = 0.0004;
const DLAT = 0.0003;
const PLOT = {
  type: 'Polygon',
  coordinates: [[[LON0, LAT0], [LON0 + DLON, LAT0], [LON0 + DLON, LAT0 + DLAT], [LON0, LAT0 + DLAT], [LON0, LAT0]]],
};

/** 3 x 3 samples, NDVI 0.3..0.7 west to east: more seeds to the east. */
function samplesCsv() {
  const rows = ['sample_id,lon,lat,n_mg_kg,ndvi'];
  let k = 0;
  for (let i = 0; i < 3; i++)
    for (let j = 0; j < 3; j++) {
      const lon = LON0 + (DLON * (i + 0.5)) / 3;
      const lat = LAT0 + (DLAT * (j + 0.5)) / 3;
      rows.push(`V${k++},${lon.toFixed(7)},${lat.toFixed(7)},80,${(0.3 + 0.2 * i).toFixed(2)}`);
    }
  return rows.join('\n') + '\n';
}

describe('variable-rate seeding', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  let planId;
  let drill;

  before(async () => {
    token = await apiLogin();
    const f = await api(token, 'POST', '/fields', { type: 'Feature', properties: { name: 'seeding e2e' }, geometry: PLOT });
    assert.ok(f.ok, `field ${f.status}`);
    const fd = new FormData();
    fd.append('file', new Blob([samplesCsv()], { type: 'text/csv' }), 'samples.csv');
    const s = await api(token, 'POST', `/fields/${f.data.id}/soil-samples`, fd);
    assert.ok(s.ok, `samples ${s.status} ${JSON.stringify(s.data)}`);
    const p = await api(token, 'POST', `/fields/${f.data.id}/plans`, { swath_width_m: 2.3, cell_length_m: 5, headland_passes: 0 });
    assert.ok(p.ok, `plan ${p.status}`);
    planId = p.data.id;
    const calibration = { kind: 'table', rpm: [5, 40], g_per_rev: [30, 30], min_rpm: 6, max_rpm: 40 };
    const m = await api(token, 'POST', '/machines', {
      name: `e2e drill ${Date.now() % 100000}`, width_m: 2.3, lag_s: 1.52, calibration, implement_type: 'seeder',
    });
    assert.ok(m.ok, `machine ${m.status} ${JSON.stringify(m.data)}`);
    drill = m.data;
    B = await launch();
    page = B.page;
    await signIn(page);
  });
  after(async () => {
    if (B) await B.close();
  });

  it('prescribes seeds/ha through a seed lot and sends a seeding job', async () => {
    await page.goto(`${BASE_URL}/#/plans/${planId}`);
    await page.waitForSelector('[data-testid=rx-form] [data-testid=rx-model]');
    await page.selectOption('[data-testid=rx-model]', 'seeding_ndvi');
    await page.waitForSelector('[data-testid=rx-param-seeds_at_low]');
    await page.selectOption('[data-testid=rx-rate-unit]', 'seeds/ha');
    await page.waitForSelector('[data-testid=rx-lot-tkw_g]');
    // a seed lot, named here: no fertiliser from the catalogue is offered for it
    await page.waitForSelector('[data-testid=rx-seed-name]');
    assert.equal(await page.$('[data-testid=rx-form] [data-testid=rx-product]'), null);
    await page.fill('[data-testid=rx-seed-name]', 'Maize P9234, lot 17');
    await page.fill('[data-testid=rx-lot-tkw_g]', '320');
    // a germination no seed lot has is refused where it was typed, and nothing is sent
    await page.fill('[data-testid=rx-lot-germination_pct]', '140');
    await page.selectOption('[data-testid=rx-machine]', '');
    await page.click('[data-testid=rx-submit]');
    await page.waitForFunction(() => /germination/i.test(document.querySelector('[data-testid=rx-form]')?.textContent ?? ''));
    assert.ok(!/#\/prescriptions\//.test(page.url()));
    await page.fill('[data-testid=rx-lot-germination_pct]', '95');
    await page.click('[data-testid=rx-submit]');
    await page.waitForURL(/#\/prescriptions\/\d+$/, { timeout: scaled(60_000) });
    const rxId = Number(page.url().match(/#\/prescriptions\/(\d+)/)[1]);
    const rx = (await api(token, 'GET', `/prescriptions/${rxId}`)).data;
    assert.equal(rx.rate_unit, 'seeds/ha');
    assert.deepEqual(rx.lot, { tkw_g: 320, germination_pct: 95 });
    assert.equal(rx.product, 'Maize P9234, lot 17');
    assert.equal(rx.summary.nutrients_kg ?? null, null);
    await page.waitForFunction(() => /seeds\/ha/.test(document.querySelector('[data-testid=rx-rate-unit]')?.textContent ?? ''));
    const text = await page.textContent('[data-testid=rx-rate-unit]');
    assert.match(text, /^seeds\/ha through .*320.*95.* · mean [\d,]+(\.\d)? seeds\/ha$/);
    const mean = Number(text.match(/mean ([\d,.]+) seeds/)[1].replace(/,/g, ''));
    assert.ok(mean >= 60_000 && mean <= 90_000, `mean ${mean}`);
    // the map's classes and the figures in seeds/ha beside the seed's kg/ha
    assert.match(await page.textContent('[data-testid=rx-legend]'), /Rate \(seeds\/ha\)/);
    assert.match(await page.textContent('[data-testid=rx-sum-mean]'), /kg\/ha · [\d,]+ seeds\/ha$/);
    assert.equal(await page.$('[data-testid=rx-sum-n]'), null, 'a seed lot carries no nutrients to show');
    await shot(page, 'rx-seeding-seeds-ha');

    await page.selectOption('[data-testid=job-machine]', String(drill.id));
    await page.click('[data-testid=send-job]');
    let job = null;
    const deadline = Date.now() + scaled(30_000);
    while (!job && Date.now() < deadline) {
      const jobs = (await api(token, 'GET', `/jobs?machine_id=${drill.id}`)).data;
      job = (jobs.items ?? jobs).find((j) => j.prescription_id === rxId) ?? null;
      if (!job) await new Promise((r) => setTimeout(r, 300));
    }
    assert.ok(job, 'the job was created');
    assert.equal(job.kind, 'seeding_rate');

    // the drill sows it (the agent's simulator, by mass through the lot) and the report
    // gives its totals in seeds beside the kilograms
    assert.ok((await api(token, 'POST', `/jobs/${job.id}/state`, { state: 'sent' })).ok);
    const dt = await api(token, 'POST', `/machines/${drill.id}/device-token`);
    const res = await fetch(`${BASE_URL}/api/v1/device/jobs/${job.id}/package`, { headers: { Authorization: `Bearer ${dt.data.token}` } });
    assert.ok(res.ok, `package ${res.status}`);
    const file = join(ARTIFACTS, `seeding-job-${job.id}.json`);
    writeFileSync(file, Buffer.from(await res.arrayBuffer()));
    const r = await run(EDGE, ['simulate', file, '--server', BASE_URL, '--token', dt.data.token, '--json'], scaled(300_000));
    writeFileSync(join(ARTIFACTS, `seeding-simulate-${job.id}.log`), r.out + r.err);
    assert.equal(r.code, 0, 'simulator exit code');
    const rep = (await api(token, 'GET', `/jobs/${job.id}/report?cells=false`)).data;
    assert.equal(rep.unit.total_unit, 'seeds');
    await page.goto(`${BASE_URL}/#/jobs/${job.id}`);
    await page.waitForSelector('[data-testid=report-unit-totals]', { timeout: scaled(30_000) });
    const totals = await page.textContent('[data-testid=report-unit-totals]');
    const shown = (totals.match(/[\d,]+ seeds/g) ?? []).map((t) => Number(t.replace(/[^\d]/g, '')));
    assert.equal(shown.length, 2, totals);
    assert.ok(Math.abs(shown[0] - rep.unit.planned_total) <= 1, `${totals} vs ${rep.unit.planned_total}`);
    assert.ok(Math.abs(shown[1] - rep.unit.applied_total) <= 1, `${totals} vs ${rep.unit.applied_total}`);
    await shot(page, 'report-seeding-seeds');
  });
});
