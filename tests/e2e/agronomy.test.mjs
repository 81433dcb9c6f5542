// Agronomic sense in the browser: the wheat case (winter wheat, 8 t/ha, CAN 27 % N, IDW from
// 60 soil samples) starts from the field's crop with every default's source beside it, gives
// a rate inside wheat's published range, shows kg N/ha next to kg/ha; pushed above the crop's
// N ceiling by edits it is flagged (count, area, cells) and sending needs a confirmation the
// job records. Set-up (field, samples, plan, the edits) through the API; the rest in the UI.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, api, apiLogin, hasRoute, launch, serverUp, shot, signIn, uiServed } from './lib.mjs';

const up = await serverUp();
const ui = up && (await uiServed());
const SKIP = !up
  ? `no server at ${BASE_URL}`
  : !ui
    ? 'server does not serve the UI'
    : !(await hasRoute('GET', '/fields/{}/rx-defaults'))
      ? 'no rx-defaults route on this server'
      : false;

// ~60 m x 40 m plot
const LON0 = 112.45;
const LAT0 = 32.26;
const DLON = 0.000636;
const DLAT = 0.000362;
const PLOT = {
  type: 'Polygon',
  coordinates: [[[LON0, LAT0], [LON0 + DLON, LAT0], [LON0 + DLON, LAT0 + DLAT], [LON0, LAT0 + DLAT], [LON0, LAT0]]],
};
const WHEAT_N_RANGE = [150, 230]; // agronomy.crops: calibration range, upper end DüV 2020

/** 60 samples, seed-style column alkali_n_mg_kg, 85..140 mg/kg (a fixed pseudo-random walk). */
function samplesCsv() {
  const rows = ['sample_id,lon,lat,alkali_n_mg_kg'];
  let x = 33;
  const rnd = () => {
    x = (x * 16807) % 2147483647;
    return x / 2147483647;
  };
  for (let i = 0; i < 60; i++) {
    const lon = LON0 + DLON * (0.02 + 0.96 * rnd());
    const lat = LAT0 + DLAT * (0.02 + 0.96 * rnd());
    rows.push(`W${i},${lon.toFixed(8)},${lat.toFixed(8)},${(85 + 55 * rnd()).toFixed(2)}`);
  }
  return rows.join('\n') + '\n';
}

describe('agronomic sense: the wheat case', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  let planId;
  let rxId;

  before(async () => {
    token = await apiLogin();
    const f = await api(token, 'POST', '/fields', { type: 'Feature', properties: { name: 'wheat e2e', crop: 'winter wheat' }, geometry: PLOT });
    assert.ok(f.ok, `field ${f.status}`);
    const fd = new FormData();
    fd.append('file', new Blob([samplesCsv()], { type: 'text/csv' }), 'wheat.csv');
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
      writeFileSync(join(ARTIFACTS, 'agronomy-browser-console.log'), B.logs.join('\n'));
      await B.close();
    }
  });

  it("starts from the field's crop, every default with its source, and gives a rate in wheat's range", async () => {
    await page.goto(`${BASE_URL}/#/plans/${planId}`);
    await page.waitForSelector('[data-testid=rx-form] [data-testid=rx-crop]');
    // the field says winter wheat: not the first crop of the list (oilseed rape)
    await page.waitForFunction(() => document.querySelector('[data-testid=rx-crop]')?.value === 'winter_wheat');
    const form = await page.textContent('[data-testid=rx-form] .rx-fields');
    assert.match(form, /default: Winter wheat, DüV 2020/, 'target yield source');
    assert.match(form, /Zhang F\. et al\. 2008/, 'utilisation source');
    assert.match(form, /calibrated/, "eq. 20's slope says it is calibrated");
    // every crop default in the UI with its source (the API's values, one row each)
    const cat = (await api(token, 'GET', '/products')).data;
    const wheat = cat.crops.find((c) => c.key === 'winter_wheat');
    await page.click('[data-testid=rx-crop-values] summary');
    for (const [k, v] of Object.entries(wheat.values)) {
      const row = await page.textContent(`[data-testid=rx-crop-value-${k}]`);
      assert.ok(row.includes(String(v.value)) && row.includes(v.source), `${k}: ${row}`);
    }
    assert.equal(await page.inputValue('[data-testid=rx-targetYieldTHa]'), '8');
    await page.selectOption('[data-testid=rx-product]', 'default:can');
    await page.selectOption('[data-testid=rx-machine]', '');
    await shot(page, 'agronomy-wheat-form');
    await page.click('[data-testid=rx-submit]');
    await page.waitForURL(/#\/prescriptions\/\d+$/, { timeout: 60_000 });
    rxId = Number(page.url().match(/#\/prescriptions\/(\d+)/)[1]);
    const rx = (await api(token, 'GET', `/prescriptions/${rxId}`)).data;
    const s = rx.summary;
    assert.equal(s.crop.key, 'winter_wheat');
    assert.equal(s.param_origin.k_utilisation, 'default');
    const [lo, hi] = WHEAT_N_RANGE;
    assert.ok(s.rate_min_kg_ha * 0.27 >= lo && s.rate_max_kg_ha * 0.27 <= hi, `${s.rate_min_kg_ha}..${s.rate_max_kg_ha} kg/ha`);
    // kg N/ha next to kg/ha of product
    await page.waitForSelector('[data-testid=rx-summary][data-version="1"]');
    const mean = await page.textContent('[data-testid=rx-sum-mean]');
    assert.match(mean, new RegExp(`${s.rate_mean_kg_ha.toFixed(1)} kg/ha · ${(s.rate_mean_kg_ha * 0.27).toFixed(1)} kg N/ha`));
    assert.match(await page.textContent('[data-testid=rx-range-n]'), /kg N\/ha/);
    assert.match(await page.textContent('[data-testid=rx-ceilings]'), /230 kg N\/ha \(Winter wheat: DüV 2020/);
    assert.equal(await page.locator('[data-testid=rx-ceiling-warn]').count(), 0);
  });

  it('pushed above the N ceiling by edits: flagged with count and area, sending needs confirmation', async () => {
    const cells = (await api(token, 'GET', `/prescriptions/${rxId}/cells?limit=3`)).data.features.map((f) => f.properties);
    const e = await api(token, 'POST', `/prescriptions/${rxId}/edits`, {
      cells: cells.map((c) => ({ seq: c.seq, rate_kg_ha: 950 })),
      note: 'pushed',
    });
    assert.ok(e.ok, `edit ${e.status} ${JSON.stringify(e.data)}`);
    const area = cells.reduce((a, c) => a + c.area_m2, 0);
    await page.reload();
    await page.waitForSelector('[data-testid=rx-ceiling-warn]');
    const warn = await page.textContent('[data-testid=rx-ceiling-warn]');
    assert.match(warn, new RegExp(`^3 cells \\(${(area / 10_000).toFixed(3)} ha\\) above a nutrient ceiling`));
    assert.match(warn, /over 230 kg N\/ha \(up to 256\.5/);
    for (const c of cells) assert.ok(warn.includes(String(c.seq)), `cell ${c.seq} listed`);
    await shot(page, 'agronomy-ceiling-flagged');
    // a machine that meters 950 kg/ha: only the ceiling needs the confirmation
    const m = await api(token, 'POST', '/machines', {
      name: `wheat spreader ${Date.now() % 100000}`,
      width_m: 2.3,
      lag_s: 1.52,
      calibration: { kind: 'linear', slope_g_min_per_rpm: 237.2, intercept_g_min: -404.4, min_rpm: 30, max_rpm: 130 },
      speed_min_m_s: 1.2,
      speed_max_m_s: 1.5,
    });
    assert.ok(m.ok, `machine ${m.status}`);
    await page.reload();
    await page.waitForSelector('[data-testid=job-machine]');
    await page.waitForFunction((id) => [...document.querySelectorAll('[data-testid=job-machine] option')].some((o) => o.value === String(id)), m.data.id);
    await page.selectOption('[data-testid=job-machine]', String(m.data.id));
    await page.click('[data-testid=send-job]');
    await page.waitForSelector('[data-testid=job-confirm-panel]');
    const text = await page.textContent('[data-testid=job-confirm-text]');
    assert.match(text, /3 cell\(s\).*3 above a nutrient ceiling.*confirm these cells/);
    assert.equal((await api(token, 'GET', `/jobs?prescription_id=${rxId}`)).data.total, 0, 'nothing sent before the confirmation');
    await shot(page, 'agronomy-confirm');
    await page.click('[data-testid=job-confirm]');
    await page.waitForURL(/#\/jobs/, { timeout: 30_000 });
    const jobs = (await api(token, 'GET', `/jobs?prescription_id=${rxId}`)).data.items;
    assert.equal(jobs.length, 1);
    assert.equal(jobs[0].flagged_cells, 3);
    assert.equal(jobs[0].flagged_confirmed, true);
  });
});
