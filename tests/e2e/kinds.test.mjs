// In the browser: create a sensor-based topdressing job (seed 000) and a seeding job
// with depth control (seed 002) through their own forms, drive each with
// `fieldrx-edge simulate --server`, and read the report (Table 3 layout, maps).
// (The prescription-map kind is created through the UI in scenario.test.mjs.)
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, ROOT, api, apiLogin, launch, listOf, mapIdle, run, serverUp, shot, signIn, uiServed, scaled } from './lib.mjs';

const up = await serverUp();
const ui = up && (await uiServed());
const EDGE = join(ROOT, '.venv', 'bin', 'fieldrx-edge');
const SKIP = !up ? `no server at ${BASE_URL}` : !ui ? 'server does not serve the UI' : !existsSync(EDGE) ? 'no fieldrx-edge' : false;

const PLOT = {
  type: 'Polygon',
  coordinates: [[[112.42, 32.23], [112.42037, 32.23], [112.42037, 32.23021], [112.42, 32.23021], [112.42, 32.23]]],
};
const SEED000_TABLE = { kind: 'table', rpm: [6, 15, 25, 40], g_per_rev: [525, 510, 498, 488], min_rpm: 6, max_rpm: 40 };


describe('job kinds in the browser', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  before(async () => {
    token = await apiLogin();
    B = await launch();
    page = B.page;
    await signIn(page);
  });
  after(async () => {
    if (B) {
      writeFileSync(join(ARTIFACTS, 'kinds-browser-console.log'), B.logs.join('\n'));
      await B.close();
    }
  });

  /** Set-up through the API (field, machine, plan); the job and its report through the UI. */
  /** A machine that can do the kind (an NDVI job needs canopy sensors, a seeding job a depth actuator and sensor). */
  async function setup(name, width, calibration, machine) {
    const f = await api(token, 'POST', '/fields', { type: 'Feature', properties: { name }, geometry: PLOT });
    assert.ok(f.ok, `field ${f.status}`);
    const m = await api(token, 'POST', '/machines', { name, width_m: width, lag_s: 1.52, calibration, ...machine });
    assert.ok(m.ok, `machine ${m.status} ${JSON.stringify(m.data)}`);
    const p = await api(token, 'POST', `/fields/${f.data.id}/plans`, { swath_width_m: width, cell_length_m: 5, headland_passes: 0 });
    assert.ok(p.ok, `plan ${p.status}`);
    return { fieldId: f.data.id, machineId: m.data.id, planId: p.data.id };
  }

  async function createThroughUi(kind, s, edit) {
    await page.goto(`${BASE_URL}/#/jobs`);
    await page.selectOption('[data-testid=job-kind]', kind);
    await page.waitForSelector(`[data-testid=job-form-${kind}]`);
    // the plan is picked by field, then one of its plans (no number typed)
    assert.equal(await page.$eval('[data-testid=job-plan]', (e) => e.tagName), 'SELECT', 'no plan number box');
    await page.waitForSelector(`[data-testid=job-field] option[value="${s.fieldId}"]`, { state: 'attached' });
    await page.selectOption('[data-testid=job-field]', String(s.fieldId));
    await page.waitForSelector(`[data-testid=job-plan] option[value="${s.planId}"]`, { state: 'attached' });
    assert.match(await page.textContent(`[data-testid=job-plan] option[value="${s.planId}"]`), new RegExp(`^Plan ${s.planId} · [\\d.]+ m swath, 5 m cells`));
    await page.selectOption('[data-testid=job-plan]', String(s.planId));
    await page.waitForSelector(`[data-testid=job-kind-machine] option[value="${s.machineId}"]`, { state: 'attached' });
    await page.selectOption('[data-testid=job-kind-machine]', String(s.machineId));
    if (edit) await edit();
    await shot(page, `kind-form-${kind}`);
    const before = listOf((await api(token, 'GET', '/jobs?limit=1')).data)[0]?.id ?? 0;
    await page.click('[data-testid=job-kind-submit]');
    let job;
    for (let i = 0; i < 50 && !job; i++) {
      job = listOf((await api(token, 'GET', '/jobs?limit=1')).data).find((j) => j.id > before && j.kind === kind);
      // a curve the machine cannot meter is sent only once confirmed, in the user's words
      const confirm = job ? null : await page.$('[data-testid=job-kind-confirm]');
      if (confirm) {
        const text = await page.textContent('[data-testid=job-kind-confirm-text]');
        assert.match(text, /can meter only/);
        assert.doesNotMatch(text, /confirm_flagged/);
        await confirm.click();
      }
      if (!job) await new Promise((r) => setTimeout(r, 200));
    }
    assert.ok(job, 'job created from the form');
    await page.waitForSelector(`[data-testid=job-source-${job.id}]`);
    return job;
  }

  /** Every legend row reads differently, and none as "30 – 30" (a narrow range is one class "30"). */
  async function legendReadsApart() {
    const rows = (await page.locator('[data-testid=report-legend] .legend-row').allTextContents()).map((r) => r.trim());
    assert.ok(rows.length >= 1, 'legend drawn');
    assert.doesNotMatch(rows.join(' | '), /no values/, 'the cells have values');
    assert.equal(new Set(rows).size, rows.length, `legend rows repeat: ${rows.join(' | ')}`);
    for (const r of rows) assert.doesNotMatch(r, /^(\S+) – \1$/, `a class reads as one value twice: ${r}`);
  }

  async function simulate(job, machineId) {
    const dt = await api(token, 'POST', `/machines/${machineId}/device-token`);
    const res = await fetch(`${BASE_URL}/api/v1/device/jobs/${job.id}/package`, { headers: { Authorization: `Bearer ${dt.data.token}` } });
    assert.ok(res.ok, `package ${res.status}`);
    const file = join(ARTIFACTS, `kind-job-${job.id}.json`);
    writeFileSync(file, Buffer.from(await res.arrayBuffer()));
    const r = await run(EDGE, ['simulate', file, '--server', BASE_URL, '--token', dt.data.token, '--json'], 300_000);
    writeFileSync(join(ARTIFACTS, `kind-simulate-${job.id}.log`), r.out + r.err);
    assert.equal(r.code, 0, 'simulator exit code');
    return JSON.parse(r.out.trim().split('\n').pop());
  }

  it('creates an NDVI topdressing job in its form and reads its report', async () => {
    const s = await setup('ndvi plot', 3.6, SEED000_TABLE, { implement_type: 'spreader', capabilities: { sensors: ['canopy_ndvi'] } });
    const job = await createThroughUi('ndvi_topdress', s, async () => {
      // the paper's values are named; the preview follows an edited curve
      assert.match(await page.textContent('[data-testid=job-form-ndvi_topdress]'), /paper default: 0\.24 NDVI/);
      await page.fill('[data-testid="set-rate_curve.rate_at_hi_kg_ha"]', '200');
      await page.waitForFunction(() => /NDVI 0\.7 → 200 kg\/ha/.test(document.querySelector('[data-testid=ndvi-preview]')?.textContent ?? ''));
    });
    assert.equal(job.settings.rate_curve.rate_at_hi_kg_ha, 200);
    assert.equal(job.settings.window, 15);
    const sim = await simulate(job, s.machineId);
    await page.goto(`${BASE_URL}/#/jobs/${job.id}`);
    await page.waitForSelector('[data-testid=shaft-table] tbody tr');
    await page.waitForFunction(
      (want) => (document.querySelector('[data-testid=report-shaft-error]')?.textContent ?? '').startsWith(want),
      sim.mean_relative_error_pct.toFixed(2),
      { timeout: scaled(30_000) },
    );
    await mapIdle(page, 'kind-report');
    const drawn = await page.evaluate(() => window.__fieldrxMaps['kind-report'].queryRenderedFeatures({ layers: ['kcells-fill'] }).length);
    assert.ok(drawn > 0, 'NDVI map drawn');
    await shot(page, 'kind-report-ndvi');
    await page.click('[data-testid=view-rate]');
    await mapIdle(page, 'kind-report');
    await shot(page, 'kind-report-rate');
  });

  it('creates a depth-controlled seeding job in its form and reads its report', async () => {
    const s = await setup('seeding plot', 2.3, { kind: 'linear', slope_g_min_per_rpm: 237.2, intercept_g_min: -404.4, min_rpm: 30, max_rpm: 130 }, { implement_type: 'seeder', capabilities: { depth_actuator: true, sensors: ['depth'] } });
    const job = await createThroughUi('seeding_depth', s, async () => {
      assert.match(await page.textContent('[data-testid=depth-band]'), /20–40 mm/);
    });
    assert.equal(job.settings.target_depth_mm, 30);
    const sim = await simulate(job, s.machineId);
    await page.goto(`${BASE_URL}/#/jobs/${job.id}`);
    await page.waitForSelector('[data-testid=depth-table] tbody tr');
    const q = sim.depth_table.all.qualified_pct.toFixed(1);
    await page.waitForFunction((want) => (document.querySelector('[data-testid=report-qualified]')?.textContent ?? '').startsWith(want), q, {
      timeout: scaled(30_000),
    });
    await mapIdle(page, 'kind-report');
    await shot(page, 'kind-report-depth');
    await legendReadsApart();
    await page.click('[data-testid=view-qualified]');
    await mapIdle(page, 'kind-report');
    await shot(page, 'kind-report-qualified');
    await legendReadsApart();
  });
});
