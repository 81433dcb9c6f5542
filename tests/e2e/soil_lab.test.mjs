// The soil-lab import assistant in the browser: a German lab's file
// (';', decimal commas, Windows-1252 umlauts, "Breite/Länge", "Nmin (kg/ha)", "P2O5 (mg/100g)",
// "Humus (%)", "Tiefe (cm)" as "0-30") is read with the columns, units and coordinate system
// recognised; the rejected row and the row outside the field are listed with row number and
// reason; the mapping and a unit are changed and the preview follows; nothing is stored
// before "Import"; replace deletes the earlier samples. The example file (ETRS89/UTM
// Rechtswert/Hochwert) round-trips through the assistant.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, EMAIL, PASSWORD, api, apiLogin, hasRoute, launch, serverUp, shot, uiServed } from './lib.mjs';

const up = (await serverUp()) && (await uiServed());
const SKIP = !up
  ? `no FieldRx server with the UI at ${BASE_URL}`
  : !(await hasRoute('POST', '/fields/{}/soil-imports/preview'))
    ? 'no soil-lab preview on this server'
    : false;

const comma = (v, d) => v.toFixed(d).replace('.', ',');

/** Windows-1252 bytes of a text (what Excel writes as "CSV (Trennzeichen-getrennt)" in Germany). */
function cp1252(text) {
  return Buffer.from([...text].map((ch) => (ch.charCodeAt(0) < 256 ? ch.charCodeAt(0) : 63)));
}

describe('soil-lab import assistant', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  let fieldId;
  let box;
  before(async () => {
    token = await apiLogin();
    // a field of its own: ~200 m x 150 m near Göttingen (UTM zone 32)
    const [lon0, lat0, dlon, dlat] = [9.9, 51.55, 0.0029, 0.00135];
    const ring = [[lon0, lat0], [lon0 + dlon, lat0], [lon0 + dlon, lat0 + dlat], [lon0, lat0 + dlat], [lon0, lat0]];
    const r = await api(token, 'POST', '/fields', {
      type: 'Feature',
      geometry: { type: 'Polygon', coordinates: [ring] },
      properties: { name: `Lab import ${Date.now()}` },
    });
    assert.equal(r.status, 201, JSON.stringify(r.data));
    fieldId = r.data.id;
    box = { lon0, lat0, dlon, dlat };
    B = await launch({ width: 1400, height: 900 });
    page = B.page;
    await page.goto(`${BASE_URL}/#/login`);
    await page.fill('[data-testid=login-email]', EMAIL);
    await page.fill('[data-testid=login-password]', PASSWORD);
    await page.click('[data-testid=login-submit]');
    await page.waitForSelector('[data-testid=field-list]');
  });
  after(async () => {
    if (B) writeFileSync(join(ARTIFACTS, 'soil-lab-browser-console.log'), B.logs.join('\n'));
    await B?.close();
    if (fieldId) await api(token, 'DELETE', `/fields/${fieldId}`);
  });

  const count = async () => Number((await page.textContent('[data-testid=soil-count]')).replace(/\D/g, ''));
  const target = (col) => page.locator(`[data-testid="soil-col-${col}"] [data-testid=soil-col-target]`);
  const unit = (col) => page.locator(`[data-testid="soil-col-${col}"] [data-testid=soil-col-unit]`);
  // a cell of the first converted row: 0 row, 1 sample, 2 lon, 3 lat, 4 depth, 5 N, 6 P, 7 K, 8 OM, 9 pH
  const cell = (i) => page.locator('[data-testid=soil-preview-rows] tbody tr').first().locator('td').nth(i).textContent();
  const previewSettled = () => page.waitForFunction(() => !document.querySelector('[data-testid=soil-busy]'));

  it('maps a German lab file, lists rejected and outside rows, stores only on confirm', async () => {
    const { lon0, lat0, dlon, dlat } = box;
    const rows = ['Probe;Breite;Länge;Tiefe (cm);Nmin (kg/ha);P2O5 (mg/100g);K2O (mg/100g);Humus (%);pH'];
    let k = 0;
    for (const fi of [0.2, 0.5, 0.8])
      for (const fj of [0.25, 0.75]) {
        k += 1;
        rows.push([`P${k}`, comma(lat0 + dlat * fj, 7), comma(lon0 + dlon * fi, 7), '0-30', String(40 + k), comma(12.5 + k, 1), comma(15.3, 1), comma(2.4, 1), comma(6.4, 1)].join(';'));
      }
    rows.push(['P7', comma(lat0 + dlat * 0.5, 7), comma(lon0 + dlon * 0.5, 7), '0-30', 'n.b.', '13,0', '15,0', '2,0', '6,5'].join(';')); // row 8
    rows.push(['P8', comma(lat0 + 0.02, 7), comma(lon0 + dlon * 0.5, 7), '0-30', '50', '13,0', '15,0', '2,0', '6,5'].join(';')); // row 9, ~2 km north
    const file = join(ARTIFACTS, 'soil-lab-de.csv');
    writeFileSync(file, cp1252(rows.join('\r\n') + '\r\n'));

    await page.goto(`${BASE_URL}/#/fields/${fieldId}`);
    await page.waitForSelector('[data-testid=soil-count]');
    assert.equal(await count(), 0);
    await page.setInputFiles('[data-testid=soil-file]', file);
    await page.waitForSelector('[data-testid=soil-mapping]');
    await previewSettled();
    // recognised: columns, units, coordinate system
    assert.equal(await target('Probe').inputValue(), 'sample_id');
    assert.equal(await target('Länge').inputValue(), 'x');
    assert.equal(await target('Breite').inputValue(), 'y');
    assert.equal(await target('Tiefe (cm)').inputValue(), 'depth');
    assert.equal(await target('Nmin (kg/ha)').inputValue(), 'n');
    assert.equal(await unit('Nmin (kg/ha)').inputValue(), 'kg/ha');
    assert.equal(await unit('P2O5 (mg/100g)').inputValue(), 'P2O5 mg/100g');
    assert.equal(await unit('K2O (mg/100g)').inputValue(), 'K2O mg/100g');
    assert.equal(await target('Humus (%)').inputValue(), 'om');
    assert.equal(await unit('Humus (%)').inputValue(), '%');
    assert.equal(await page.locator('[data-testid=soil-crs]').inputValue(), '4326');
    assert.match(await page.textContent('[data-testid=soil-mapping]'), /decimal comma/);
    // counts and the lists with row number and reason
    assert.equal(await page.textContent('[data-testid=soil-n-rejected]'), '1');
    assert.equal(await page.textContent('[data-testid=soil-n-outside]'), '1');
    const rejected = await page.textContent('[data-testid=soil-rejected]');
    assert.match(rejected, /row 8, Nmin \(kg\/ha\): expected a number, got 'n\.b\.'/);
    assert.match(await page.textContent('[data-testid=soil-outside]'), /row 9 \(P8\): 2,\d{3} m away/);
    // converted values (first row): P2O5 13.5 mg/100 g -> 58.92 mg P/kg; humus 2.4 % -> 24 g/kg
    assert.equal(await cell(6), '58.92');
    assert.equal(await cell(8), '24');
    await shot(page, 'soil-lab-mapping');
    // a rejected row blocks the import until the user chooses to leave it out
    assert.ok(await page.isDisabled('[data-testid=soil-confirm]'));
    await page.check('[data-testid=soil-skip-rejected]');
    assert.match(await page.textContent('[data-testid=soil-confirm]'), /Import 6 samples/);
    // nothing stored yet
    assert.equal((await api(token, 'GET', `/fields/${fieldId}/soil-samples`)).data.features.length, 0);

    // the user says Nmin is mg/kg: the preview follows (41 kg/ha was 41 * 10 / (30 * 1.5) = 9.11 mg/kg)
    assert.equal(await cell(5), '9.11');
    await unit('Nmin (kg/ha)').selectOption('mg/kg');
    await page.waitForFunction(
      () => document.querySelector('[data-testid=soil-preview-rows] tbody tr')?.querySelectorAll('td')[5]?.textContent === '41',
    );
    // ...and humus is not to be read
    await target('Humus (%)').selectOption('');
    await previewSettled();
    assert.equal(await target('Humus (%)').inputValue(), '');
    await page.click('[data-testid=soil-confirm]');
    await page.waitForSelector('[data-testid=soil-result]');
    assert.match(await page.textContent('[data-testid=soil-result]'), /6 samples imported/);
    await page.waitForFunction(() => document.querySelector('[data-testid=soil-count]')?.textContent?.startsWith('6'));
    const stored = (await api(token, 'GET', `/fields/${fieldId}/soil-samples`)).data.features;
    assert.equal(stored.length, 6);
    const p1 = stored.find((f) => f.properties.sample_id === 'P1').properties;
    assert.equal(p1.n_mg_kg, 41);
    assert.equal(p1.om_pct, null);
    assert.equal(p1.depth_cm, 30);
    await shot(page, 'soil-lab-imported');
  });

  it('imports the example file (Rechtswert/Hochwert, ETRS89/UTM) replacing the samples', async () => {
    const [download] = await Promise.all([page.waitForEvent('download'), page.click('[data-testid=soil-example]')]);
    const file = join(ARTIFACTS, 'soil-lab-example.csv');
    await download.saveAs(file);
    const text = readFileSync(file, 'utf8');
    assert.match(text, /^Probe;Rechtswert;Hochwert;Tiefe \(cm\);Nmin \(kg\/ha\)/);
    await page.setInputFiles('[data-testid=soil-file]', file);
    await page.waitForSelector('[data-testid=soil-mapping]');
    await previewSettled();
    assert.equal(await page.locator('[data-testid=soil-crs]').inputValue(), '25832');
    assert.equal(await page.textContent('[data-testid=soil-n-outside]'), '0');
    assert.equal(await page.textContent('[data-testid=soil-n-rejected]'), '0');
    // the wrong coordinate system puts every row outside (the count says so) and blocks the import
    await page.selectOption('[data-testid=soil-crs]', '31467');
    await page.waitForFunction(() => document.querySelector('[data-testid=soil-n-outside]')?.textContent !== '0');
    assert.ok(await page.isDisabled('[data-testid=soil-confirm]'));
    await page.selectOption('[data-testid=soil-crs]', '25832');
    await page.waitForFunction(() => document.querySelector('[data-testid=soil-n-outside]')?.textContent === '0');
    await page.check('[data-testid=soil-mode-replace]');
    assert.match(await page.textContent('[data-testid=soil-confirm]'), /Import 9 samples \(replacing 6\)/);
    await page.click('[data-testid=soil-confirm]');
    await page.waitForSelector('[data-testid=soil-result]:has-text("6 earlier samples replaced")');
    await page.waitForFunction(() => document.querySelector('[data-testid=soil-count]')?.textContent?.startsWith('9'));
    assert.equal(await page.locator('[data-testid=soil-imports] tbody tr').count(), 1);
    await shot(page, 'soil-lab-example-replaced');
  });
});
