// In the browser: the prescription form with typed fields (no JSON), the
// version switch showing that version's summary, undo / redo of a rate edit (buttons and
// Ctrl+Z / Ctrl+Shift+Z), and the diff of two versions. Set-up (field, samples, plan)
// through the API; everything under test through the UI, checked against the API's figures.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, api, apiLogin, hasRoute, launch, mapIdle, serverUp, shot, signIn, uiServed, scaled } from './lib.mjs';

const up = await serverUp();
const ui = up && (await uiServed());
const SKIP = !up
  ? `no server at ${BASE_URL}`
  : !ui
    ? 'server does not serve the UI'
    : !(await hasRoute('GET', '/prescriptions/{}/diff'))
      ? 'no diff route on this server'
      : false;

// ~45 m x 33 m plot
const LON0 = 112.43;
const LAT0 = 32.24;
const DLON = 0.00048;
const DLAT = 0.0003;
const PLOT = {
  type: 'Polygon',
  coordinates: [[[LON0, LAT0], [LON0 + DLON, LAT0], [LON0 + DLON, LAT0 + DLAT], [LON0, LAT0 + DLAT], [LON0, LAT0]]],
};

/** 3 x 3 samples, soil N 60..140 mg/kg: rates vary, so a clamp has cells to change. */
function samplesCsv() {
  const rows = ['sample_id,lon,lat,n_mg_kg'];
  let k = 0;
  for (let i = 0; i < 3; i++)
    for (let j = 0; j < 3; j++) {
      const lon = LON0 + (DLON * (i + 0.5)) / 3;
      const lat = LAT0 + (DLAT * (j + 0.5)) / 3;
      rows.push(`E${k++},${lon.toFixed(7)},${lat.toFixed(7)},${60 + 10 * (3 * i + j)}`);
    }
  return rows.join('\n') + '\n';
}

const kgText = (kg) => (Math.abs(kg) >= 10_000 ? `${(kg / 1000).toFixed(3)} t` : `${kg.toFixed(1)} kg`);

describe('prescription screen', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  let planId;
  let rxId;
  const productName = `E2E CAN ${Date.now() % 100000}`;

  before(async () => {
    token = await apiLogin();
    const f = await api(token, 'POST', '/fields', { type: 'Feature', properties: { name: 'rx screen e2e' }, geometry: PLOT });
    assert.ok(f.ok, `field ${f.status}`);
    const fd = new FormData();
    fd.append('file', new Blob([samplesCsv()], { type: 'text/csv' }), 'samples.csv');
    const s = await api(token, 'POST', `/fields/${f.data.id}/soil-samples`, fd);
    assert.ok(s.ok, `samples ${s.status} ${JSON.stringify(s.data)}`);
    const p = await api(token, 'POST', `/fields/${f.data.id}/plans`, { swath_width_m: 2.3, cell_length_m: 5, headland_passes: 0 });
    assert.ok(p.ok, `plan ${p.status}`);
    planId = p.data.id;
    B = await launch();
    page = B.page;
    await signIn(page);
  });
  after(async () => {
    if (B) {
      writeFileSync(join(ARTIFACTS, 'rxscreen-browser-console.log'), B.logs.join('\n'));
      await B.close();
    }
  });

  it('builds a prescription from typed fields, a new product and a clamp (no JSON)', async () => {
    await page.goto(`${BASE_URL}/#/plans/${planId}`);
    await page.waitForSelector('[data-testid=rx-form] [data-testid=rx-crop]');
    assert.equal(await page.locator('[data-testid=rx-form] textarea').count(), 0, 'no JSON box');
    await page.selectOption('[data-testid=rx-model]', 'nutrient_balance');
    await page.selectOption('[data-testid=rx-crop]', 'winter_rape');
    // the crop's defaults say where they come from
    assert.match(await page.textContent('[data-testid=rx-form] .rx-fields'), /seed 001/);
    await page.fill('[data-testid=rx-targetYieldTHa]', '2.5');
    // a product of the organisation, added in the form
    await page.click('[data-testid=rx-product-add]');
    await page.fill('[data-testid=product-name]', productName);
    await page.fill('[data-testid=product-n]', '27');
    await page.fill('[data-testid=product-price]', '350');
    await page.click('[data-testid=product-save]');
    await page.waitForFunction(
      (n) => document.querySelector('[data-testid=rx-product] option:checked')?.textContent?.includes(n),
      productName,
    );
    assert.match(await page.textContent('[data-testid=rx-product-info]'), /27 % N.*350 \/t/);
    // a clamp the agronomist sets; a bad one is refused next to the field, nothing sent
    await page.fill('[data-testid=rx-clampMin]', '900');
    await page.fill('[data-testid=rx-clampMax]', '800');
    await page.click('[data-testid=rx-submit]');
    await page.waitForSelector('[data-testid=rx-clampMax-error]');
    assert.match(await page.textContent('[data-testid=rx-clampMax-error]'), /below the minimum/);
    // soil N 60..140 mg/kg with 27 % N: model rates ~594..703 kg/ha
    await page.fill('[data-testid=rx-clampMin]', '620');
    await page.fill('[data-testid=rx-clampMax]', '680');
    await page.selectOption('[data-testid=rx-machine]', '');
    await page.fill('[data-testid=rx-note]', 'e2e first pass');
    await shot(page, 'rx-form-typed');
    await page.click('[data-testid=rx-submit]');
    await page.waitForURL(/#\/prescriptions\/\d+$/, { timeout: scaled(60_000) });
    rxId = Number(page.url().match(/#\/prescriptions\/(\d+)/)[1]);
    const rx = (await api(token, 'GET', `/prescriptions/${rxId}`)).data;
    assert.equal(rx.params.target_yield_kg_ha, 2500);
    assert.equal(rx.params.n_fraction, 0.27);
    assert.equal(rx.product, productName);
    const s = rx.summary;
    assert.deepEqual([s.clamp.min_kg_ha, s.clamp.max_kg_ha], [620, 680]);
    assert.ok(s.clamp.raised > 0 && s.clamp.lowered > 0, JSON.stringify(s.clamp));
    assert.ok(s.clamp.count > 0, 'the clamp changed cells (reported)');
    await page.waitForSelector('[data-testid=rx-summary][data-version="1"]');
    // the model in words, not the API's identifier
    assert.equal(await page.textContent('[data-testid=rx-model-name]'), 'Nutrient balance (soil N)');
    await page.waitForFunction(() => /kg N\/ha/.test(document.querySelector('[data-testid=rx-sum-n]')?.textContent ?? ''));
    assert.equal(await page.textContent('[data-testid=rx-sum-product]'), kgText(s.product_kg));
    assert.match(await page.textContent('[data-testid=rx-sum-n]'), new RegExp(`${s.nutrients_kg_ha.N.toFixed(1)} kg N/ha`));
    assert.equal(await page.textContent('[data-testid=rx-sum-cost]'), s.cost.toLocaleString('en-US', { maximumFractionDigits: 2 }));
    const clampText = await page.textContent('[data-testid=rx-clamp]');
    assert.match(clampText, new RegExp(`${s.flagged.clamped_min} cells? raised, ${s.flagged.clamped_max} lowered`));
    assert.equal(await page.textContent('[data-testid=rx-note-text]'), 'e2e first pass');
    const zonesT = Number(await page.textContent('[data-testid=rx-zones-t]'));
    assert.ok(Math.abs(zonesT - s.product_kg / 1000) < 0.002, `zones table total ${zonesT} t vs ${s.product_kg} kg`);
    await mapIdle(page, 'rx');
    await shot(page, 'rx-screen-v1');
  });

  async function clickACell() {
    await mapIdle(page, 'rx');
    const box = await page.locator('[data-testid=map-rx] canvas').first().boundingBox();
    const pt = await page.evaluate(() => {
      const map = window.__fieldrxMaps.rx;
      const fs = map.queryRenderedFeatures({ layers: ['rx-fill'] });
      const f = fs[Math.floor(fs.length / 2)];
      if (!f) return null;
      const ring = f.geometry.type === 'Polygon' ? f.geometry.coordinates[0] : f.geometry.coordinates[0][0];
      const c = ring.slice(0, -1).reduce((a, p) => [a[0] + p[0] / (ring.length - 1), a[1] + p[1] / (ring.length - 1)], [0, 0]);
      return map.project(c);
    });
    assert.ok(pt, 'a rendered cell to click');
    await page.mouse.click(box.x + pt.x, box.y + pt.y);
    await page.waitForSelector('[data-testid=cell-new-rate]');
  }

  const current = async () => (await api(token, 'GET', `/prescriptions/${rxId}`)).data.current_version;
  const waitVersion = (v) =>
    page.waitForFunction((x) => document.querySelector('[data-testid=rx-version]')?.value === String(x), v, { timeout: scaled(20_000) });

  it('edits a cell; switching versions shows that version\'s summary', async (t) => {
    if (!rxId) return t.skip('needs the prescription');
    await clickACell();
    await page.fill('[data-testid=cell-new-rate]', '1200');
    await page.click('[data-testid=cell-save]');
    await page.waitForSelector('[data-testid=rx-msg]:has-text("version 2")');
    await waitVersion(2);
    const v1 = (await api(token, 'GET', `/prescriptions/${rxId}/versions/1`)).data.summary;
    const v2 = (await api(token, 'GET', `/prescriptions/${rxId}/versions/2`)).data.summary;
    assert.notEqual(v1.product_kg, v2.product_kg);
    const showing = async (v, s) => {
      await page.waitForSelector(`[data-testid=rx-summary][data-version="${v}"]`);
      await page.waitForFunction(
        (want) => document.querySelector('[data-testid=rx-sum-product]')?.textContent === want,
        kgText(s.product_kg),
        { timeout: scaled(10_000) },
      );
      assert.match(await page.textContent('[data-testid=rx-sum-mean]'), new RegExp(s.rate_mean_kg_ha.toFixed(1).replace('.', '\\.')));
    };
    await showing(2, v2);
    await page.selectOption('[data-testid=rx-version]', '1');
    await showing(1, v1);
    assert.equal(await page.textContent('[data-testid=rx-note-text]'), 'e2e first pass');
    assert.equal(await page.locator('[data-testid=rx-legend] .legend-row[data-outline]').count(), 0, 'v1 has no edits');
    await page.selectOption('[data-testid=rx-version]', '2');
    await showing(2, v2);
    assert.match(await page.textContent('[data-testid=rx-note-text]'), /cell \d+ → 1,200\.0 kg\/ha/);
    // the edited cell is told apart: a class of its own beyond v1's breaks, and a dashed
    // outline with its own legend row (not only the colour of the unedited cells' class)
    await page.waitForSelector('[data-testid=rx-legend] .legend-row[data-outline]');
    assert.match(await page.textContent('[data-testid=rx-legend] .legend-row[data-outline]'), /Edited by hand: 1 cell\b/);
    const rows = await page.locator('[data-testid=rx-legend] .legend-row:not([data-outline])').allTextContents();
    assert.equal(rows.length, v2.classes.breaks_kg_ha.length - 1, 'one row per class');
    assert.match(rows[rows.length - 1], /1200$/, `the edited rate's own class: ${rows}`);
    assert.equal(v2.classes.table[v2.classes.table.length - 1].n_cells, 1, 'only the edited cell in it');
    assert.equal(new Set(rows).size, rows.length, `legend rows repeat: ${rows}`);
    assert.equal((v2.classes.source.match(/edited rates/g) ?? []).length, 1, v2.classes.source);
    await mapIdle(page, 'rx');
    const outlined = await page.evaluate(() => window.__fieldrxMaps.rx.queryRenderedFeatures({ layers: ['rx-edited'] }).length);
    assert.ok(outlined >= 1, 'the edited cell is outlined on the map');
    await shot(page, 'rx-screen-v2');
  });

  it('undoes and redoes the edit (buttons and keyboard)', async (t) => {
    if (!rxId) return t.skip('needs the prescription');
    assert.equal(await current(), 2);
    await page.click('[data-testid=rx-undo]');
    await waitVersion(1);
    assert.equal(await current(), 1, 'undo made version 1 current');
    await page.click('[data-testid=rx-redo]');
    await waitVersion(2);
    assert.equal(await current(), 2, 'redo made version 2 current');
    // keyboard, with the focus outside any input
    await page.click('h2');
    await page.keyboard.press('Control+z');
    await waitVersion(1);
    assert.equal(await current(), 1);
    await page.keyboard.press('Control+Shift+z');
    await waitVersion(2);
    assert.equal(await current(), 2);
    assert.equal(await page.isDisabled('[data-testid=rx-redo]'), true, 'nothing left to redo');
  });

  it('diffs two versions', async (t) => {
    if (!rxId) return t.skip('needs the prescription');
    await page.selectOption('[data-testid=rx-diff-from]', '1');
    await page.selectOption('[data-testid=rx-diff-to]', '2');
    await page.click('[data-testid=rx-diff-run]');
    await page.waitForSelector('[data-testid=rx-diff-result]');
    const d = (await api(token, 'GET', `/prescriptions/${rxId}/diff?from=1&to=2`)).data;
    assert.equal(d.cells_changed, 1);
    assert.equal(await page.textContent('[data-testid=rx-diff-cells]'), '1');
    assert.equal(await page.textContent('[data-testid=rx-diff-area]'), `${d.area_changed_ha.toFixed(3)} ha`);
    assert.equal(await page.textContent('[data-testid=rx-diff-product]'), `+${kgText(d.product_kg_delta)}`);
    assert.equal(await page.textContent('[data-testid=rx-diff-cost]'), `+${d.cost_delta.toFixed(2)}`);
    await shot(page, 'rx-diff');
  });
});
