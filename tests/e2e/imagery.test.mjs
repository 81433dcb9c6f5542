// Imagery in the browser: upload an orthophoto on a field, see it under the field's
// boundary (tiles served and drawn below the data layers), pick it and change its opacity,
// and find it under the boundary editor's map; maps open fitted to the fields; NDVI and soil zones.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, EMAIL, PASSWORD, ROOT, api, apiLogin, hasRoute, launch, mapIdle, serverUp, shot, uiServed, scaled } from './lib.mjs';

const up = (await serverUp()) && (await uiServed());
const SKIP = !up
  ? `no FieldRx server with the UI at ${BASE_URL}`
  : !(await hasRoute('POST', '/fields/{}/imagery'))
    ? 'no imagery upload on this server'
    : false;

/** An RGB GeoTIFF (rasterio, EPSG:4326) covering bbox plus a margin: magenta/green stripes. */
function writeOrthophoto(file, bbox) {
  const py = `
import sys, numpy as np, rasterio
from rasterio.transform import from_bounds
w, s, e, n = map(float, sys.argv[2:6])
mx, my = (e - w) * 0.2, (n - s) * 0.2
W = H = 512
stripes = ((np.arange(W)[None, :] // 32) % 2).repeat(H, 0)
rgb = np.stack([np.where(stripes, 230, 40), np.where(stripes, 20, 200), np.where(stripes, 230, 40)]).astype('uint8')
with rasterio.open(sys.argv[1], 'w', driver='GTiff', width=W, height=H, count=3, dtype='uint8', crs='EPSG:4326',
                   transform=from_bounds(w - mx, s - my, e + mx, n + my, W, H), tiled=True) as d:
    d.write(rgb)
`;
  execFileSync(join(ROOT, '.venv', 'bin', 'python'), ['-c', py, file, ...bbox.map(String)]);
}

/** A float32 NDVI GeoTIFF (EPSG:4326) over bbox plus a margin: NDVI 0.2 -> 0.8 west -> east. */
function writeNdvi(file, bbox) {
  const py = `
import sys, numpy as np, rasterio
from rasterio.transform import from_bounds
w, s, e, n = map(float, sys.argv[2:6])
mx, my = (e - w) * 0.2, (n - s) * 0.2
W = H = 400
nd = np.tile(np.linspace(0.2, 0.8, W, dtype='float32'), (H, 1))
with rasterio.open(sys.argv[1], 'w', driver='GTiff', width=W, height=H, count=1, dtype='float32', crs='EPSG:4326',
                   transform=from_bounds(w - mx, s - my, e + mx, n + my, W, H), tiled=True) as d:
    d.write(nd, 1)
`;
  execFileSync(join(ROOT, '.venv', 'bin', 'python'), ['-c', py, file, ...bbox.map(String)]);
}

describe('imagery under the maps', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  let field;
  const tileStatus = [];
  before(async () => {
    token = await apiLogin();
    const fc = (await api(token, 'GET', '/fields?limit=500')).data;
    field = fc.features.find((f) => f.bbox);
    B = await launch();
    page = B.page;
    page.on('response', (r) => {
      if (r.url().includes('/api/v1/tiles/imagery/')) tileStatus.push(r.status());
    });
  });
  after(async () => {
    if (B) writeFileSync(join(ARTIFACTS, 'imagery-browser-console.log'), B.logs.join('\n'));
    await B?.close();
  });

  it('opens the fields map fitted to the fields, not the world', async () => {
    await page.goto(`${BASE_URL}/#/login`);
    await page.fill('[data-testid=login-email]', EMAIL);
    await page.fill('[data-testid=login-password]', PASSWORD);
    await page.click('[data-testid=login-submit]');
    await page.waitForSelector('[data-testid=field-list]');
    await mapIdle(page, 'fields');
    const zoom = await page.evaluate(() => window.__fieldrxMaps.fields.getZoom());
    assert.ok(zoom > 8, `fields map zoom ${zoom} is not at field scale`);
  });

  it('uploads an orthophoto on a field and draws it under the boundary', async () => {
    assert.ok(field, 'the demo organisation has a field');
    const file = join(ARTIFACTS, 'orthophoto.tif');
    writeOrthophoto(file, field.bbox);
    await page.goto(`${BASE_URL}/#/fields/${field.id}`);
    await mapIdle(page, 'field');
    await page.click('[data-testid=imagery-toggle]');
    await page.setInputFiles('[data-testid=imagery-file]', file);
    await page.selectOption('[data-testid=imagery-kind]', 'orthophoto');
    await page.click('[data-testid=imagery-upload]');
    await page.waitForSelector('[data-testid=imagery-msg]:has-text("Stored")', { timeout: scaled(60_000) });
    await page.waitForFunction(() => Boolean(window.__fieldrxMaps.field.getLayer('imagery')));
    await mapIdle(page, 'field');
    const order = await page.evaluate(() => window.__fieldrxMaps.field.getStyle().layers.map((l) => l.id));
    const at = order.indexOf('imagery');
    assert.ok(at >= 0, 'imagery layer added');
    assert.ok(order.length > at + 1, `data layers drawn above the imagery: ${order.join(', ')}`);
    assert.ok(tileStatus.includes(200), `imagery tiles served (statuses ${tileStatus.join(',')})`);
    assert.ok(!tileStatus.some((s) => s >= 400), `no failed imagery tile (statuses ${tileStatus.join(',')})`);
    assert.equal(await page.locator('[data-testid=imagery-legend]').count(), 0, 'a photo has no NDVI legend');
    await shot(page, 'imagery-under-field');
  });

  it('picker and opacity control the layer', async () => {
    await page.locator('[data-testid=imagery-opacity]').fill('40');
    const op = await page.evaluate(() => window.__fieldrxMaps.field.getPaintProperty('imagery', 'raster-opacity'));
    assert.equal(op, 0.4);
    await page.selectOption('[data-testid=imagery-select]', '');
    await page.waitForFunction(() => !window.__fieldrxMaps.field.getLayer('imagery'));
    const items = (await api(token, 'GET', `/fields/${field.id}/imagery`)).data.items;
    await page.selectOption('[data-testid=imagery-select]', String(items[0].id));
    await page.waitForFunction(() => Boolean(window.__fieldrxMaps.field.getLayer('imagery')));
  });

  it('the boundary editor draws on the imagery', async () => {
    await page.goto(`${BASE_URL}/#/fields/${field.id}/edit`);
    await page.waitForSelector('[data-testid=map-draw]');
    await shot(page, 'editor-before-imagery');
    await page.waitForFunction(() => Boolean(window.__fieldrxMaps?.draw?.getLayer('imagery')), null, { timeout: scaled(20_000) });
    await mapIdle(page, 'draw');
    await shot(page, 'imagery-under-editor');
  });

  it('uploads an NDVI raster, builds an NDVI prescription and a 4-zone prescription', async () => {
    const file = join(ARTIFACTS, 'ndvi.tif');
    writeNdvi(file, field.bbox);
    await page.goto(`${BASE_URL}/#/fields/${field.id}`);
    await mapIdle(page, 'field');
    await page.click('[data-testid=imagery-toggle]');
    await page.setInputFiles('[data-testid=imagery-file]', file);
    await page.selectOption('[data-testid=imagery-kind]', 'ndvi');
    await page.click('[data-testid=imagery-upload]');
    await page.waitForSelector('[data-testid=imagery-msg]:has-text("Stored ndvi")', { timeout: scaled(60_000) });
    // the NDVI raster shown has its value legend: the ramp the tiles are drawn with, 0 to 1
    await page.waitForSelector('[data-testid=imagery-legend]');
    const ticks = await page.locator('[data-testid=imagery-legend] .ndvi-ticks span').allTextContents();
    assert.deepEqual(ticks, ['0.00', '0.25', '0.50', '0.75', '1.00']);
    const ramp = await page.$eval('[data-testid=imagery-legend] .ndvi-ramp', (e) => getComputedStyle(e).backgroundImage);
    assert.match(ramp, /linear-gradient\(to right, rgb\(165, 0, 38\)/, ramp);
    await shot(page, 'imagery-ndvi-legend');
    const plan = await api(token, 'POST', `/fields/${field.id}/plans`, { swath_width_m: 2.3, cell_length_m: 5 });
    assert.equal(plan.status, 201, JSON.stringify(plan.data));

    await page.goto(`${BASE_URL}/#/plans/${plan.data.id}`);
    await page.waitForSelector('[data-testid=imagery-rx-form]');
    await page.selectOption('[data-testid=imagery-rx-mode]', 'ndvi');
    await page.click('[data-testid=imagery-rx-submit]');
    await page.waitForURL(/#\/prescriptions\/\d+/, { timeout: scaled(60_000) });
    const ndviRx = (await api(token, 'GET', `/prescriptions/${page.url().split('/').pop()}`)).data;
    assert.equal(ndviRx.model, 'ndvi');
    assert.equal(ndviRx.interpolation, 'imagery');
    await mapIdle(page, 'rx');
    await shot(page, 'ndvi-prescription-from-imagery');

    await page.goto(`${BASE_URL}/#/plans/${plan.data.id}`);
    await page.waitForSelector('[data-testid=imagery-rx-form]');
    await page.selectOption('[data-testid=imagery-rx-mode]', 'zones');
    await page.fill('[data-testid=imagery-rx-k]', '4');
    await page.click('[data-testid=imagery-rx-submit]');
    await page.waitForURL((u) => /#\/prescriptions\/\d+/.test(u.toString()) && !u.toString().endsWith(`/${ndviRx.id}`), {
      timeout: scaled(60_000),
    });
    const zoneId = page.url().split('/').pop();
    const zoneRx = (await api(token, 'GET', `/prescriptions/${zoneId}`)).data;
    assert.equal(zoneRx.summary.interpolation.zones.length, 4);
    await mapIdle(page, 'rx');
    await shot(page, 'zone-prescription-from-imagery');
    const r = await fetch(`${BASE_URL}/api/v1/prescriptions/${zoneId}/export?format=isoxml-zones`, {
      headers: { Authorization: `Bearer ${token}` },
    });
    assert.equal(r.status, 200);
    assert.equal(Buffer.from(await r.arrayBuffer()).subarray(0, 2).toString(), 'PK');
  });

  it('builds a 3-zone prescription from soil samples with the control next to the NDVI zones', async () => {
    // soil N rising west -> east on a 5 x 5 grid around the field's centre (inside it or
    // stored with include_outside): the zones must come out ordered by N
    const [w, s, e, n] = field.bbox;
    const cx = (w + e) / 2;
    const cy = (s + n) / 2;
    const rows = ['sample_id,lon,lat,n_mg_kg'];
    for (let i = 0; i < 5; i++) {
      for (let j = 0; j < 5; j++) {
        const lon = cx + ((i - 2) / 2) * (e - w) * 0.3;
        const lat = cy + ((j - 2) / 2) * (n - s) * 0.3;
        rows.push(`Z${Date.now()}-${i}-${j},${lon.toFixed(8)},${lat.toFixed(8)},${50 + 15 * i + j}`);
      }
    }
    const form = new FormData();
    form.append('file', new Blob([rows.join('\n') + '\n'], { type: 'text/csv' }), 'zones.csv');
    const up = await fetch(`${BASE_URL}/api/v1/fields/${field.id}/soil-samples?include_outside=true`, {
      method: 'POST',
      headers: { Authorization: `Bearer ${token}` },
      body: form,
    });
    assert.equal(up.status, 201, await up.text());
    const plan = await api(token, 'POST', `/fields/${field.id}/plans`, { swath_width_m: 2.3, cell_length_m: 5 });
    assert.equal(plan.status, 201, JSON.stringify(plan.data));
    await page.goto(`${BASE_URL}/#/plans/${plan.data.id}`);
    await page.waitForSelector('[data-testid=soil-zones-form]');
    await page.selectOption('[data-testid=soil-zones-model]', 'nutrient_balance');
    await page.fill('[data-testid=soil-zones-k]', '3');
    await page.fill('[data-testid=soil-zones-min-area]', '100');
    await page.click('[data-testid=soil-zones-submit]');
    await page.waitForURL(/#\/prescriptions\/\d+/, { timeout: scaled(60_000) });
    const rx = (await api(token, 'GET', `/prescriptions/${page.url().split('/').pop()}`)).data;
    assert.equal(rx.model, 'nutrient_balance');
    const zones = rx.summary.interpolation.zones;
    assert.equal(zones.length, 3);
    const means = zones.map((z) => z.mean_n_mg_kg);
    assert.deepEqual([...means].sort((a, b) => a - b), means);
    await mapIdle(page, 'rx');
    await shot(page, 'zone-prescription-from-soil');
  });
});
