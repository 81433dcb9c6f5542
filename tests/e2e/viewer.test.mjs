// A viewer signs in and sees the fields but none of the controls that would write.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { BASE_URL, PASSWORD, launch, mapIdle, serverUp, shot, uiServed } from './lib.mjs';

const VIEWER = process.env.FIELDRX_VIEWER_EMAIL ?? 'viewer@demo.fieldrx.org';
const up = (await serverUp()) && (await uiServed());

describe('viewer role', { skip: up ? false : `no FieldRx server with the UI at ${BASE_URL}` }, () => {
  let B;
  before(async () => {
    B = await launch();
  });
  after(async () => {
    await B?.close();
  });

  it('hides write controls from a viewer', async (t) => {
    const { page } = B;
    await page.goto(`${BASE_URL}/#/login`);
    await page.fill('[data-testid=login-email]', VIEWER);
    await page.fill('[data-testid=login-password]', process.env.FIELDRX_VIEWER_PASSWORD ?? PASSWORD);
    await page.click('[data-testid=login-submit]');
    const outcome = await Promise.race([
      page.waitForSelector('[data-testid=field-list]').then(() => 'in'),
      page.waitForSelector('[data-testid=login-error]').then(() => 'refused'),
    ]);
    if (outcome === 'refused') return t.skip(`no viewer account ${VIEWER} on this server`);
    assert.match(await page.textContent('[data-testid=org-name]'), /viewer/);
    await mapIdle(page, 'fields');
    assert.equal(await page.locator('[data-testid=new-field]').isVisible(), false, 'no "Draw new field" for a viewer');
    assert.equal(await page.locator('[data-testid=field-list] li').count() > 0, true, 'fields are listed');
    await shot(page, 'viewer-fields');
  });
});
