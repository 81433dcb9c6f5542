// In the browser: the job report's loading state and the
// progress of its background task, the printable as-applied report (print media: field,
// date, machine, product, totals, map, legend shown; the screen's controls hidden), and the
// export buttons producing files (inline, and through an export task with progress).
// Set-up through the API and `fieldrx-edge simulate --server`; the report is what is tested.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, ROOT, api, apiLogin, launch, mapIdle, run, serverUp, shot, signIn, uiServed, scaled } from './lib.mjs';

const up = await serverUp();
const ui = up && (await uiServed());
const EDGE = join(ROOT, '.venv', 'bin', 'fieldrx-edge');
const SKIP = !up ? `no server at ${BASE_URL}` : !ui ? 'server does not serve the UI' : !existsSync(EDGE) ? 'no fieldrx-edge' : false;

const PLOT = {
  type: 'Polygon',
  coordinates: [[[112.43, 32.24], [112.43037, 32.24], [112.43037, 32.24021], [112.43, 32.24021], [112.43, 32.24]]],
};
const FIELD = 'report plot';
const PRODUCT = 'Urea 46 % N';


describe('job report: loading, print, exports', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  let job;
  let machineName;
  before(async () => {
    token = await apiLogin();
    const f = await api(token, 'POST', '/fields', { type: 'Feature', properties: { name: FIELD }, geometry: PLOT });
    assert.ok(f.ok, `field ${f.status}`);
    machineName = `report spreader ${Date.now()}`;
    const calibration = { kind: 'linear', slope_g_min_per_rpm: 237.2, intercept_g_min: -404.4, min_rpm: 5, max_rpm: 130 };
    const m = await api(token, 'POST', '/machines', { name: machineName, width_m: 3.6, lag_s: 1.52, calibration });
    assert.ok(m.ok, `machine ${m.status} ${JSON.stringify(m.data)}`);
    const p = await api(token, 'POST', `/fields/${f.data.id}/plans`, { swath_width_m: 3.6, cell_length_m: 5, headland_passes: 0 });
    assert.ok(p.ok, `plan ${p.status}`);
    const rx = await api(token, 'POST', `/plans/${p.data.id}/prescriptions`, {
      model: 'uniform',
      params: { rate_kg_ha: 150 },
      product: PRODUCT,
      name: 'report rx',
    });
    assert.ok(rx.ok, `prescription ${rx.status} ${JSON.stringify(rx.data)}`);
    const j = await api(token, 'POST', '/jobs', { prescription_id: rx.data.id, machine_id: m.data.id, confirm_flagged: true });
    assert.ok(j.ok, `job ${j.status} ${JSON.stringify(j.data)}`);
    job = j.data;
    assert.ok((await api(token, 'POST', `/jobs/${job.id}/state`, { state: 'sent' })).ok);
    const dt = await api(token, 'POST', `/machines/${m.data.id}/device-token`);
    const res = await fetch(`${BASE_URL}/api/v1/device/jobs/${job.id}/package`, { headers: { Authorization: `Bearer ${dt.data.token}` } });
    assert.ok(res.ok, `package ${res.status}`);
    const file = join(ARTIFACTS, `report-job-${job.id}.json`);
    writeFileSync(file, Buffer.from(await res.arrayBuffer()));
    const r = await run(EDGE, ['simulate', file, '--server', BASE_URL, '--token', dt.data.token, '--json'], 300_000);
    writeFileSync(join(ARTIFACTS, `report-simulate-${job.id}.log`), r.out + r.err);
    assert.equal(r.code, 0, 'simulator exit code');

    B = await launch();
    page = B.page;
    await signIn(page);
  });
  after(async () => {
    if (B) {
      writeFileSync(join(ARTIFACTS, 'report-browser-console.log'), B.logs.join('\n'));
      await B.close();
    }
  });

  it("follows the report task's progress when the server computes it in the background", async () => {
    const pattern = `**/api/v1/jobs/${job.id}/report*`;
    // as the server answers a large job: 202 with a report task (run by the e2e worker)
    await page.route(pattern, (route) => route.continue({ url: `${route.request().url()}&background=true` }));
    const before = (await api(token, 'GET', `/tasks?kind=report&limit=1`)).data.items[0]?.id ?? 0;
    // the first visit of the report: nothing computed it yet
    await page.goto(`${BASE_URL}/#/jobs/${job.id}`);
    const sawTask = await page
      .waitForSelector('[data-testid=report-loading] [data-testid=task-progress]', { timeout: scaled(10_000) })
      .then(() => true)
      .catch(() => false);
    await page.waitForFunction(() => /^[1-9]/.test(document.querySelector('[data-testid=report-records]')?.textContent ?? ''), null, {
      timeout: scaled(60_000),
    });
    const tasks = (await api(token, 'GET', `/tasks?kind=report&limit=5`)).data.items.filter((t) => t.id > before);
    assert.ok(sawTask, 'the task progress was shown while the report was computed');
    assert.equal(tasks.length, 1, 'one report task (polling joins it)');
    assert.equal(tasks[0].status, 'succeeded', JSON.stringify(tasks[0]));
    await shot(page, 'report-after-task');
    await page.unroute(pattern);
  });

  it('shows a loading state, then the report (no "0 records" meanwhile)', async () => {
    // a slow report answer (a large job): hold it back 2.5 s
    const pattern = `**/api/v1/jobs/${job.id}/report*`;
    await page.route(pattern, async (route) => {
      await new Promise((r) => setTimeout(r, 2500));
      await route.continue();
    });
    // a fresh mount of the report screen (two hash changes in one go may render only the last)
    await page.goto(`${BASE_URL}/#/jobs`);
    await page.waitForSelector('[data-testid=job-table]');
    await page.goto(`${BASE_URL}/#/jobs/${job.id}`);
    await page.waitForSelector('[data-testid=report-loading]', { state: 'visible', timeout: scaled(10_000) });
    assert.match(await page.textContent('[data-testid=report-loading]'), /Loading the report/);
    assert.equal((await page.textContent('[data-testid=report-records]')).trim(), '…');
    assert.doesNotMatch(await page.textContent('[data-testid=report-cells]'), /\b0\b/);
    await shot(page, 'report-loading');
    await page.waitForSelector('[data-testid=report-loading]', { state: 'detached', timeout: scaled(30_000) });
    await page.waitForFunction(() => /^[1-9]/.test(document.querySelector('[data-testid=report-records]')?.textContent ?? ''));
    await page.unroute(pattern);
  });

  it('prints an as-applied report with field, date, machine, product, totals, map and legend', async () => {
    await page.goto(`${BASE_URL}/#/jobs/${job.id}`);
    await page.waitForFunction(() => /^[1-9]/.test(document.querySelector('[data-testid=report-records]')?.textContent ?? ''), null, {
      timeout: scaled(60_000),
    });
    await mapIdle(page, 'report');
    await page.evaluate(() => {
      window.__printed = 0;
      window.print = () => {
        window.__printed += 1;
      };
    });
    await page.click('[data-testid=report-print]');
    assert.equal(await page.evaluate(() => window.__printed), 1, 'window.print called');
    await page.emulateMedia({ media: 'print' });
    const visible = async (sel) => page.isVisible(sel);
    assert.ok(await visible('[data-testid=print-report]'), 'printed report shown');
    assert.match(await page.textContent('[data-testid=print-field]'), new RegExp(FIELD));
    assert.match(await page.textContent('[data-testid=print-machine]'), new RegExp(machineName));
    assert.match(await page.textContent('[data-testid=print-product]'), /Urea 46 % N/);
    assert.match(await page.textContent('[data-testid=print-date]'), /\d{4}-\d\d-\d\d \d\d:\d\d UTC/);
    const totals = await page.textContent('[data-testid=print-totals]');
    for (const k of ['Planned', 'Applied', 'Coverage', 'Mean accuracy', 'Time worked']) assert.match(totals, new RegExp(k));
    assert.match(totals, /Applied\s*[0-9.,]+\s*(kg|t)/);
    assert.ok(await visible('[data-testid=print-legend]'), 'legend printed');
    const img = await page.evaluate(() => {
      const el = document.querySelector('[data-testid=print-map]');
      return el ? { w: el.naturalWidth, vis: el.getBoundingClientRect().width, src: el.src.slice(0, 22) } : null;
    });
    assert.ok(img && img.w > 100 && img.vis > 100 && img.src.startsWith('data:image/png'), `map image ${JSON.stringify(img)}`);
    // the screen's controls are not printed
    for (const sel of ['[data-testid=export-buttons]', '[data-testid=replay-slider]', '[data-testid=view-applied]', '[data-testid=report-print]', '.topbar', '.map-wrap'])
      assert.equal(await visible(sel), false, `${sel} hidden in print`);
    await page.screenshot({ path: join(ARTIFACTS, 'report-print.png'), fullPage: true });
    await page.pdf({ path: join(ARTIFACTS, 'report-print.pdf'), format: 'A4' }).catch(() => undefined);
    await page.emulateMedia({ media: 'screen' });
    assert.equal(await visible('[data-testid=print-report]'), false, 'print-only part hidden on screen');
  });

  it('exports CSV inline and a Shapefile through an export task, both as files', async () => {
    await page.goto(`${BASE_URL}/#/jobs/${job.id}`);
    await page.waitForSelector('[data-testid=export-csv]');
    const [csv] = await Promise.all([page.waitForEvent('download', { timeout: scaled(30_000) }), page.click('[data-testid=export-csv]')]);
    assert.match(csv.suggestedFilename(), /^job\d+_as_applied\.csv$/);
    const text = readFileSync(await csv.path(), 'utf8');
    assert.match(text.split('\n')[0], /^seq,swath,area_m2,target_rate_kg_ha,applied_rate_kg_ha/);
    assert.ok(text.trim().split('\n').length > 2, 'cell rows');
    await page.waitForSelector('[data-testid=export-note]:has-text("Saved")');

    // a large job's export: the server queues it (forced here) and the button follows the task
    const pattern = `**/api/v1/jobs/${job.id}/export*`;
    await page.route(pattern, (route) => route.continue({ url: `${route.request().url()}&background=true` }));
    const dl = page.waitForEvent('download', { timeout: scaled(60_000) });
    await page.click('[data-testid=export-shapefile]');
    const sawTask = await page
      .waitForSelector('[data-testid=export-buttons] [data-testid=task-progress]', { timeout: scaled(10_000) })
      .then(() => true)
      .catch(() => false);
    const shp = await dl;
    assert.match(shp.suggestedFilename(), /^job\d+_as_applied\.zip$/);
    const zip = readFileSync(await shp.path());
    assert.equal(zip.subarray(0, 2).toString(), 'PK', 'a zip file');
    const tasks = (await api(token, 'GET', '/tasks?kind=export&limit=1')).data.items;
    assert.equal(tasks[0].status, 'succeeded');
    assert.equal(tasks[0].result.media_type, 'application/zip');
    assert.ok(sawTask || tasks[0].status === 'succeeded');
    await shot(page, 'report-exported');
    await page.unroute(pattern);
  });

  it('lists jobs with machine, field, product and dates', async () => {
    await page.goto(`${BASE_URL}/#/jobs`);
    await page.waitForSelector(`[data-testid=job-row-${job.id}]`);
    assert.match(await page.textContent(`[data-testid=job-product-${job.id}]`), /Urea 46 % N/);
    assert.match(await page.textContent(`[data-testid=job-field-${job.id}]`), new RegExp(FIELD));
    assert.match(await page.textContent(`[data-testid=job-machine-${job.id}]`), new RegExp(machineName));
    assert.match(await page.textContent(`[data-testid=job-started-${job.id}]`), /\d{4}-\d\d-\d\d \d\d:\d\d/);
    await shot(page, 'jobs-list');
  });
});
