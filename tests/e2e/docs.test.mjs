// /docs (Swagger UI) and /redoc render from the app's own copies of their assets: every
// request the page makes goes to the FieldRx server on 127.0.0.1, none leaves the machine.
// ReDoc's bundle hard-codes one outside URL (its footer logo on cdn.redoc.ly): the docs
// pages' Content-Security-Policy (fieldrx.apidocs.DOCS_CSP) stops it in the browser, so
// the only outside request the page tries must be one the browser blocked, never sent.
import { after, before, describe, it } from 'node:test';
import assert from 'node:assert/strict';
import { BASE_URL, launch, serverUp, shot, scaled } from './lib.mjs';

const up = await serverUp();
const LOCAL = new URL(BASE_URL).origin;

describe('offline API docs', { skip: up ? false : `no FieldRx server at ${BASE_URL}` }, () => {
  let B;
  before(async () => {
    B = await launch();
  });
  after(async () => {
    await B?.close();
  });

  /** Opens a page and records every request it makes (data:/blob: URLs are in-page). */
  async function visit(path) {
    const { page } = B;
    const requests = [];
    const blocked = new Set();
    const onRequest = (r) => requests.push(r.url());
    const onFailed = (r) => {
      // Chromium reports a request its CSP refused as 'csp' (older: net::ERR_BLOCKED_BY_CSP)
      if (/^csp$|ERR_BLOCKED_BY_(CSP|CLIENT)/.test(r.failure()?.errorText ?? '')) blocked.add(r.url());
    };
    page.on('request', onRequest);
    page.on('requestfailed', onFailed);
    await page.goto(`${BASE_URL}${path}`, { waitUntil: 'networkidle' });
    return {
      page,
      /** Requests to anywhere but this server that the browser did not block itself. */
      outside: () =>
        requests.filter((u) => !u.startsWith(LOCAL + '/') && !/^(data|blob):/.test(u) && !blocked.has(u)),
      blocked,
      requests,
      stop: () => {
        page.off('request', onRequest);
        page.off('requestfailed', onFailed);
      },
    };
  }

  it('/docs renders Swagger UI with Authorize and the first-call guide, all from 127.0.0.1', async () => {
    const v = await visit('/docs');
    const { page } = v;
    await page.waitForSelector('.swagger-ui .info .title', { timeout: scaled(30_000) });
    assert.match(await page.textContent('.swagger-ui .info .title'), /FieldRx/);
    assert.ok(await page.locator('.swagger-ui .info').getByText('First call').count(), 'first-call guide shown');
    assert.ok(await page.locator('button.authorize').count(), 'Authorize button (bearer security scheme)');
    assert.ok((await page.locator('.opblock').count()) > 40, 'operations listed');
    await page.click('button.authorize');
    await page.waitForSelector('.modal-ux input', { timeout: scaled(10_000) }); // the bearer token field
    await shot(page, 'docs-swagger');
    v.stop();
    assert.ok(v.requests.some((u) => u.includes('/docs-assets/swagger-ui-bundle.js')), v.requests.join('\n'));
    assert.deepEqual(v.outside(), [], 'requests that left the machine');
  });

  it('/redoc renders ReDoc, all from 127.0.0.1', async () => {
    const v = await visit('/redoc');
    const { page } = v;
    await page.waitForSelector('h1:has-text("FieldRx")', { timeout: scaled(60_000) });
    assert.ok(await page.getByText('First call').count(), 'first-call guide shown');
    await shot(page, 'docs-redoc');
    v.stop();
    assert.deepEqual(v.outside(), [], 'requests that left the machine');
    assert.ok([...v.blocked].every((u) => u.startsWith('https://cdn.redoc.ly/')), [...v.blocked].join('\n'));
  });
});
