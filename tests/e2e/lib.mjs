// Shared helpers for the browser tests: playwright-core from frontend/node_modules
// (one `npm ci` installs everything), Debian's chromium, screenshots, API calls.
import { spawn } from 'node:child_process';
import { createRequire } from 'node:module';
import { mkdirSync, mkdtempSync, rmSync } from 'node:fs';
import { cpus, loadavg, tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
export const ROOT = join(here, '..', '..');
export const ARTIFACTS = join(here, 'artifacts');
const require = createRequire(join(ROOT, 'frontend', 'package.json'));
export const { chromium } = require('playwright-core');

export const BASE_URL = (process.env.FIELDRX_URL ?? 'http://127.0.0.1:8000').replace(/\/$/, '');
export const EMAIL = process.env.FIELDRX_EMAIL ?? 'agronomist@demo.fieldrx.org';
export const PASSWORD = process.env.FIELDRX_PASSWORD ?? 'fieldrx-demo';
export const CHROMIUM = process.env.CHROMIUM_PATH ?? '/usr/bin/chromium';

/**
 * How much longer than on a quiet machine a wait may take (tests/support/__init__.py time_scale:
 * FIELDRX_TEST_TIME_SCALE, else 2 + the 1-minute load per core, at most 12). Waits end
 * when their condition holds, so a generous scale only delays a failure.
 */
export function timeScale() {
  const env = Number(process.env.FIELDRX_TEST_TIME_SCALE);
  if (env) return Math.max(1, env);
  return Math.min(12, 2 + loadavg()[0] / cpus().length);
}

/** A timeout of `ms` on a quiet machine, stretched by timeScale(). */
export const scaled = (ms) => Math.round(ms * timeScale());

export const CHROME_FLAGS = [
  '--headless',
  '--no-sandbox',
  '--disable-gpu',
  '--disable-quic',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
];

/** Fresh profile each run; returns {context, page, close}. */
export async function launch({ width = 1280, height = 800 } = {}) {
  mkdirSync(ARTIFACTS, { recursive: true });
  const profile = mkdtempSync(join(tmpdir(), 'fieldrx-chromium-'));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: CHROMIUM,
    headless: true,
    args: CHROME_FLAGS,
    viewport: { width, height },
    acceptDownloads: true,
  });
  // Playwright's own 30 s default for waits without an explicit timeout, scaled
  context.setDefaultTimeout(scaled(30_000));
  const page = context.pages()[0] ?? (await context.newPage());
  const logs = [];
  page.on('console', (m) => logs.push(`[${m.type()}] ${m.text()}`));
  page.on('pageerror', (e) => logs.push(`[pageerror] ${e.message}`));
  return {
    context,
    page,
    logs,
    async close() {
      await context.close().catch(() => {});
      rmSync(profile, { recursive: true, force: true });
    },
  };
}

let shotNo = 0;
export async function shot(page, name) {
  shotNo += 1;
  const file = join(ARTIFACTS, `${String(shotNo).padStart(2, '0')}-${name}.png`);
  await page.screenshot({ path: file });
  return file;
}

/** Resolves when the named map has loaded and is idle (all tiles and sources drawn). */
export async function mapIdle(page, name, timeout = scaled(20_000)) {
  await page.waitForFunction((n) => Boolean(window.__fieldrxMaps?.[n]), name, { timeout });
  await page.evaluate(
    (n) =>
      new Promise((resolve) => {
        const map = window.__fieldrxMaps[n];
        if (map.loaded() && !map.isMoving() && map.areTilesLoaded()) return resolve(true);
        map.once('idle', () => resolve(true));
        map.triggerRepaint();
      }),
    name,
  );
}

/** Tiny API client for set-up steps (the UI is what is under test, not these calls). */
export async function apiLogin(email = EMAIL, password = PASSWORD) {
  const r = await fetch(`${BASE_URL}/api/v1/auth/login`, {
    method: 'POST',
    headers: { 'Content-Type': 'application/json' },
    body: JSON.stringify({ email, password }),
  });
  if (!r.ok) throw new Error(`login ${r.status}: ${await r.text()}`);
  return (await r.json()).access_token;
}

export async function api(token, method, path, body) {
  const headers = { Authorization: `Bearer ${token}` };
  let payload;
  if (body instanceof FormData) payload = body;
  else if (body !== undefined) {
    headers['Content-Type'] = 'application/json';
    payload = JSON.stringify(body);
  }
  const r = await fetch(`${BASE_URL}/api/v1${path}`, { method, headers, body: payload });
  const text = await r.text();
  let data = null;
  try {
    data = text ? JSON.parse(text) : null;
  } catch {
    data = text;
  }
  return { status: r.status, ok: r.ok, data };
}

let routes = null;
/**
 * True when the server's OpenAPI lists `method path` (path written with {} for
 * parameters, e.g. "/prescriptions/{}"): tells "endpoint not built yet" apart
 * from "resource not found".
 */
export async function hasRoute(method, path) {
  if (!routes) {
    routes = [];
    for (const u of [`${BASE_URL}/api/v1/openapi.json`, `${BASE_URL}/openapi.json`]) {
      try {
        const r = await fetch(u);
        if (!r.ok) continue;
        const spec = await r.json();
        for (const [p, ops] of Object.entries(spec.paths ?? {}))
          for (const m of Object.keys(ops)) routes.push(`${m.toUpperCase()} ${p.replace(/\{[^}]+\}/g, '{}').replace(/^\/api\/v1/, '')}`);
        break;
      } catch {
        /* try the next location */
      }
    }
  }
  return routes.includes(`${method.toUpperCase()} ${path}`);
}

export async function serverUp() {
  try {
    const r = await fetch(`${BASE_URL}/api/v1/health`, { signal: AbortSignal.timeout(3000) });
    return r.ok;
  } catch {
    return false;
  }
}

/** Does the server serve the built UI at / ? */
export async function uiServed() {
  try {
    const r = await fetch(`${BASE_URL}/`, { signal: AbortSignal.timeout(3000) });
    return r.ok && (await r.text()).includes('<div id="root">');
  } catch {
    return false;
  }
}

export function listOf(r) {
  if (Array.isArray(r)) return r;
  for (const k of ['items', 'results', 'features', 'jobs', 'machines', 'alerts', 'plans'])
    if (r && Array.isArray(r[k])) return r[k];
  return [];
}

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/** Run a command to its end (killed after `timeout` ms): `{ code, out, err }` (stdout, stderr). */
export function run(cmd, args, timeout) {
  return new Promise((resolve) => {
    const p = spawn(cmd, args, { stdio: ['ignore', 'pipe', 'pipe'] });
    let out = '';
    let err = '';
    p.stdout.on('data', (d) => (out += d));
    p.stderr.on('data', (d) => (err += d));
    const timer = setTimeout(() => p.kill('SIGTERM'), scaled(timeout));
    p.on('close', (code) => {
      clearTimeout(timer);
      resolve({ code, out, err });
    });
  });
}

/** Sign in through the login screen as the demo agronomist (or EMAIL/PASSWORD). */
export async function signIn(page) {
  await page.goto(`${BASE_URL}/#/login`);
  await page.fill('[data-testid=login-email]', EMAIL);
  await page.fill('[data-testid=login-password]', PASSWORD);
  await page.click('[data-testid=login-submit]');
  await page.waitForSelector('[data-testid=field-list]');
}
