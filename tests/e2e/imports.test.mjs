// One import in the browser for every format FieldRx reads: each file goes in through the
// Fields screen's "Import…", FieldRx recognises it, shows the server's preview, takes the
// mapping where one is needed, stores on "Import" and the result appears where the user
// looks: a TASKDATA set with holes (GreenDB's 13 partfields) in the fields list and
// matched, not duplicated, when imported again; a prescription grid (FieldRx's own
// TASKDATA export) on the prescription screen with its totals; an as-applied CSV and the
// TimeLogs of a TASKDATA as job reports; a prescription Shapefile with its rate column.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, EMAIL, PASSWORD, ROOT, api, apiLogin, hasRoute, launch, serverUp, shot, uiServed } from './lib.mjs';

const up = (await serverUp()) && (await uiServed());
const SKIP = !up
  ? `no FieldRx server with the UI at ${BASE_URL}`
  : !(await hasRoute('POST', '/imports/isoxml'))
    ? 'no ISOXML import on this server'
    : false;

const PARTFIELDS = join(ROOT, 'tests', 'formats', 'data', 'isoxml-dotnet_partfields', 'TASKDATA.XML');
const T = 60_000; // generous: previews parse and plan on a busy machine

async function download(token, path, name) {
  const r = await fetch(`${BASE_URL}/api/v1${path}`, { headers: { Authorization: `Bearer ${token}` } });
  assert.equal(r.status, 200, `${path}: ${r.status}`);
  const file = join(ARTIFACTS, name);
  writeFileSync(file, Buffer.from(await r.arrayBuffer()));
  return file;
}

describe('import assistant', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  const box = { lon0: 10.3, lat0: 52.3, dlon: 0.0029, dlat: 0.0018 }; // ~200 x 200 m in Lower Saxony
  const stamp = Date.now();
  let fieldId;
  let rxId;
  let jobId;

  const fieldCount = async () => Number((await page.textContent('[data-testid=field-count]')).replace(/\D/g, ''));
  /** Choose files with Fields' "Import…" and wait for the assistant to recognise them. */
  async function choose(files, kind) {
    await page.goto(`${BASE_URL}/#/fields`);
    await page.waitForSelector('[data-testid=field-list]');
    await page.setInputFiles('[data-testid=import-file]', files);
    await page.waitForSelector(`[data-testid=import-kind][data-kind="${kind}"]`, { timeout: T });
  }
  async function confirmAndOpen() {
    await page.click('[data-testid=import-confirm]');
    await page.waitForSelector('[data-testid=import-assistant-result]', { timeout: T });
    const msg = await page.textContent('[data-testid=import-assistant-result]');
    // the link is drawn with the message or not at all: waiting for an absent one would
    // sit out the whole default timeout
    const linkSel = '[data-testid=import-assistant-link]';
    const link = (await page.locator(linkSel).count()) ? await page.getAttribute(linkSel, 'href') : null;
    return { msg, link };
  }

  before(async () => {
    token = await apiLogin();
    const { lon0, lat0, dlon, dlat } = box;
    const ring = [[lon0, lat0], [lon0 + dlon, lat0], [lon0 + dlon, lat0 + dlat], [lon0, lat0 + dlat], [lon0, lat0]];
    const f = await api(token, 'POST', '/fields', {
      type: 'Feature',
      geometry: { type: 'Polygon', coordinates: [ring] },
      properties: { name: `Import target ${stamp}` },
    });
    assert.equal(f.status, 201, JSON.stringify(f.data));
    fieldId = f.data.id;
    const p = await api(token, 'POST', `/fields/${fieldId}/plans`, { swath_width_m: 12, cell_length_m: 10 });
    assert.equal(p.status, 201, JSON.stringify(p.data));
    const r = await api(token, 'POST', `/plans/${p.data.id}/prescriptions`, {
      name: `Uniform ${stamp}`,
      model: 'uniform',
      params: { rate_kg_ha: 150 },
    });
    assert.equal(r.status, 201, JSON.stringify(r.data));
    rxId = r.data.id;
    B = await launch({ width: 1400, height: 1000 });
    page = B.page;
    await page.goto(`${BASE_URL}/#/login`);
    await page.fill('[data-testid=login-email]', EMAIL);
    await page.fill('[data-testid=login-password]', PASSWORD);
    await page.click('[data-testid=login-submit]');
    await page.waitForSelector('[data-testid=field-list]');
  });
  after(async () => {
    if (B) writeFileSync(join(ARTIFACTS, 'imports-browser-console.log'), B.logs.join('\n'));
    await B?.close();
  });

  it('a TASKDATA with fields and holes: previewed, stored, listed, and matched on re-import', async () => {
    const before = await fieldCount();
    await choose(PARTFIELDS, 'isoxml');
    await page.waitForSelector('[data-testid=import-fields] tbody tr', { timeout: T });
    assert.equal(await page.locator('[data-testid=import-fields] tbody tr').count(), 13);
    // name, area, holes, kept, position, match: the field with its hole, new
    const [name, area, holes, , , match] = await page.locator('[data-testid=import-field-PFD12] td').allTextContents();
    assert.equal(name, 'NM_Oxted_NullMeridian_Hole');
    assert.match(area, /^3\.5\d ha$/); // the writer declares 35,600 m2 (outer ring less the hole)
    assert.equal(holes, '1');
    assert.equal(match, 'new');
    await shot(page, 'import-taskdata-preview');
    const { msg } = await confirmAndOpen();
    assert.match(msg, /Imported 13 field\(s\)/);
    await page.fill('[data-testid=field-search]', 'NM_Oxted_NullMeridian_Hole');
    await page.waitForFunction(() => document.querySelector('[data-testid=field-list]').textContent.includes('NM_Oxted_NullMeridian_Hole'));
    await page.fill('[data-testid=field-search]', '');
    await page.waitForFunction((n) => Number(document.querySelector('[data-testid=field-count]').textContent.replace(/\D/g, '')) === n, before + 13);
    // the same set again: every field is found, none created twice
    await choose(PARTFIELDS, 'isoxml');
    await page.waitForSelector('[data-testid=import-field-PFD12]', { timeout: T });
    assert.match(await page.textContent('[data-testid=import-field-PFD12]'), /matches field #\d+/);
    const again = await confirmAndOpen();
    assert.match(again.msg, /Imported 0 field\(s\) \(13 matched existing\)/);
    assert.equal(await fieldCount(), before + 13);
  });

  it('an as-applied table with its mapping becomes a job report', async () => {
    const { lon0, lat0, dlon, dlat } = box;
    const rows = ['lon,lat,APPLIED,SPEED,TIME'];
    for (let i = 0; i < 60; i++) {
      const x = lon0 + dlon * (0.1 + 0.8 * (i / 59));
      rows.push(`${x.toFixed(7)},${(lat0 + dlat * 0.5).toFixed(7)},148.5,2.5,${1_700_000_000 + i}`);
    }
    const csv = join(ARTIFACTS, `as_applied_${stamp}.csv`);
    writeFileSync(csv, rows.join('\n'));
    await choose(csv, 'as-applied');
    await page.selectOption('[data-testid=import-target-rx]', String(rxId));
    await page.waitForSelector('[data-testid=import-map-rate_column]', { timeout: T });
    assert.equal(await page.inputValue('[data-testid=import-map-rate_column]'), 'APPLIED');
    await page.selectOption('[data-testid=import-map-speed_column]', 'SPEED');
    await page.fill('[data-testid=import-width]', '12');
    await page.waitForFunction(() => /60 records, mean applied 148\.5 kg\/ha/.test(document.querySelector('[data-testid=import-mapping]')?.textContent ?? ''), null, { timeout: T });
    await shot(page, 'import-asapplied-preview');
    const { msg, link } = await confirmAndOpen();
    assert.match(msg, /Imported 60 records as job \d+/);
    jobId = Number(link.split('/').pop());
    await page.click('[data-testid=import-assistant-link]');
    await page.waitForFunction(() => /^\d+$/.test(document.querySelector('[data-testid=report-records]')?.textContent?.trim() ?? ''), null, { timeout: T });
    assert.equal((await page.textContent('[data-testid=report-records]')).trim(), '60');
    await shot(page, 'import-asapplied-report');
  });

  it('the TimeLogs of a TASKDATA: mentioned in its preview, imported as a job report', async () => {
    assert.ok(jobId, 'needs the as-applied job of the previous test');
    const zip = await download(token, `/jobs/${jobId}/export?format=isoxml`, `job_${stamp}_TASKDATA.zip`);
    await choose(zip, 'isoxml');
    await page.waitForSelector('[data-testid=import-timelogs]', { timeout: T });
    assert.match(await page.textContent('[data-testid=import-timelogs]'), /TLG00001.*60 records/);
    await page.selectOption('[data-testid=import-kind-select]', 'timelog');
    await page.selectOption('[data-testid=import-target-rx]', String(rxId));
    await page.waitForSelector('[data-testid=import-logs] tbody tr', { timeout: T });
    const row = await page.textContent('[data-testid=import-logs] tbody tr');
    assert.match(row, /TLG00001/);
    assert.match(row, /60 records/);
    await page.fill('[data-testid=import-width]', '12');
    const { msg } = await confirmAndOpen();
    assert.match(msg, /Imported 60 records as job \d+/);
    await page.click('[data-testid=import-assistant-link]');
    await page.waitForFunction(() => (document.querySelector('[data-testid=report-records]')?.textContent ?? '').trim() === '60', null, { timeout: T });
    await shot(page, 'import-timelog-report');
  });

  it('a TASKDATA with a prescription grid shows its totals on the prescription screen', async () => {
    const zip = await download(token, `/prescriptions/${rxId}/export?format=isoxml`, `rx_${stamp}_TASKDATA.zip`);
    await choose(zip, 'isoxml');
    await page.waitForSelector('[data-testid=import-prescriptions]', { timeout: T });
    const rx = await page.textContent('[data-testid=import-prescriptions]');
    assert.match(rx, /grid type 2/);
    assert.match(rx, /–150\.0 kg\/ha/); // grid cells outside the field hold 0
    // the confirm runs as a background import task: its progress shows until it is done
    await page.click('[data-testid=import-confirm]');
    await page.waitForSelector('[data-testid=import-isoxml] [data-testid=task-progress]', { timeout: T });
    const stage = await page.textContent('[data-testid=import-isoxml] [data-testid=task-progress]');
    assert.match(stage, /Importing\s+(Waiting for a worker…|\d+ % · .+|Done)/);
    await page.waitForSelector('[data-testid=import-assistant-result]', { timeout: T });
    const link = await page.getAttribute('[data-testid=import-assistant-link]', 'href');
    assert.match(link, /#\/prescriptions\/\d+/);
    // the task holds what was created: the prescription the result links to
    const tasks = await api(token, 'GET', '/tasks?kind=import');
    assert.equal(tasks.status, 200, JSON.stringify(tasks.data));
    const task = tasks.data.items[0];
    assert.equal(task.status, 'succeeded', JSON.stringify(task));
    assert.equal(`#/prescriptions/${task.result.created.prescriptions[0].id}`, link);
    await page.click('[data-testid=import-assistant-link]');
    await page.waitForSelector('[data-testid=rx-sum-area]', { timeout: T });
    const field = await api(token, 'GET', `/fields/${fieldId}`);
    const ha = field.data.properties.area_m2 / 10_000;
    const area = Number((await page.textContent('[data-testid=rx-sum-area]')).match(/[\d.]+/)[0]);
    assert.ok(Math.abs(area - ha) / ha < 0.01, `area ${area} ha vs field ${ha} ha`);
    const product = await page.textContent('[data-testid=rx-sum-product]');
    assert.doesNotMatch(product, /^\s*0(\.0+)?\s*kg/);
    await shot(page, 'import-grid-prescription');
  });

  it('a prescription Shapefile with its attribute mapping', async () => {
    const zip = await download(token, `/prescriptions/${rxId}/export?format=shapefile`, `north_rx_${stamp}.zip`);
    await choose(zip, 'rx-shapefile');
    await page.selectOption('[data-testid=import-target-field]', String(fieldId));
    await page.waitForSelector('[data-testid=import-rate-column]', { timeout: T });
    await page.selectOption('[data-testid=import-rate-column]', 'RATE');
    await page.fill('[data-testid=import-default-rate]', '100');
    await page.waitForFunction(() => /RATE in kg\/ha: 150\.0–150\.0 kg\/ha, 100\.0 kg\/ha outside/.test(document.querySelector('[data-testid=import-mapping]')?.textContent ?? ''), null, { timeout: T });
    await shot(page, 'import-rx-shapefile-mapping');
    const { link } = await confirmAndOpen();
    assert.match(link, /#\/prescriptions\/\d+/);
    await page.click('[data-testid=import-assistant-link]');
    await page.waitForSelector('[data-testid=rx-sum-product]', { timeout: T });
    assert.doesNotMatch(await page.textContent('[data-testid=rx-sum-product]'), /^\s*0(\.0+)?\s*kg/);
  });
});
