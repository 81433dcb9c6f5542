// A liquid product in the browser: its density typed in the products form, a uniform
// prescription sent to machines in l/ha, the screen showing the unit and the mean rate in
// l/ha; checked against the API. Set-up (field, plan) through the API.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { BASE_URL, api, apiLogin, launch, serverUp, shot, signIn, uiServed } from './lib.mjs';

const up = await serverUp();
const ui = up && (await uiServed());
const SKIP = !up ? `no server at ${BASE_URL}` : !ui ? 'server does not serve the UI' : false;

const LON0 = 112.44;
const LAT0 = 32.25;
const PLOT = {
  type: 'Polygon',
  coordinates: [[[LON0, LAT0], [LON0 + 0.0004, LAT0], [LON0 + 0.0004, LAT0 + 0.0003], [LON0, LAT0 + 0.0003], [LON0, LAT0]]],
};

describe('a liquid prescribed in l/ha', { skip: SKIP }, () => {
  let B;
  let page;
  let token;
  let planId;
  const productName = `E2E ATS ${Date.now() % 100000}`;

  before(async () => {
    token = await apiLogin();
    const f = await api(token, 'POST', '/fields', { type: 'Feature', properties: { name: 'liquid e2e' }, geometry: PLOT });
    assert.ok(f.ok, `field ${f.status}`);
    const p = await api(token, 'POST', `/fields/${f.data.id}/plans`, { swath_width_m: 2.3, cell_length_m: 5, headland_passes: 0 });
    assert.ok(p.ok, `plan ${p.status}`);
    planId = p.data.id;
    B = await launch();
    page = B.page;
    await signIn(page);
  });
  after(async () => {
    if (B) await B.close();
  });

  it('takes a product density and sends the prescription in l/ha', async () => {
    await page.goto(`${BASE_URL}/#/plans/${planId}`);
    await page.waitForSelector('[data-testid=rx-form] [data-testid=rx-model]');
    await page.selectOption('[data-testid=rx-model]', 'uniform');
    await page.fill('[data-testid=rx-uniformRate]', '132');
    await page.click('[data-testid=rx-product-add]');
    await page.fill('[data-testid=product-name]', productName);
    await page.fill('[data-testid=product-n]', '12');
    // a density no liquid has is refused where it was typed
    await page.fill('[data-testid=product-density]', '40');
    await page.click('[data-testid=product-save]');
    await page.waitForSelector('[data-testid=product-error]');
    assert.match(await page.textContent('[data-testid=product-error]'), /density_kg_l/);
    await page.fill('[data-testid=product-density]', '1.32');
    await page.click('[data-testid=product-save]');
    await page.waitForFunction(
      (n) => document.querySelector('[data-testid=rx-product] option:checked')?.textContent?.includes(n),
      productName,
    );
    assert.match(await page.textContent('[data-testid=rx-product-info]'), /liquid, 1\.32 kg\/l/);
    await page.selectOption('[data-testid=rx-rate-unit]', 'l/ha');
    await page.selectOption('[data-testid=rx-machine]', '');
    await page.click('[data-testid=rx-submit]');
    await page.waitForURL(/#\/prescriptions\/\d+$/, { timeout: 60_000 });
    const rxId = Number(page.url().match(/#\/prescriptions\/(\d+)/)[1]);
    const rx = (await api(token, 'GET', `/prescriptions/${rxId}`)).data;
    assert.equal(rx.rate_unit, 'l/ha');
    assert.equal(rx.density_kg_l, 1.32);
    // 132 kg/ha at 1.32 kg/l = 100 l/ha
    await page.waitForFunction(() => /l\/ha/.test(document.querySelector('[data-testid=rx-rate-unit]')?.textContent ?? ''));
    assert.equal(await page.textContent('[data-testid=rx-rate-unit]'), 'l/ha through 1.32 kg/l · mean 100.0 l/ha');
    await shot(page, 'rx-liquid-l-ha');
  });
});
