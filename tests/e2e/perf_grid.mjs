#!/usr/bin/env node
// Time to first full render of a 100,000-cell prescription grid in headless
// Chromium, through the real prescription screen (vector tiles, bearer token via
// transformRequest). Tiles come from gridserver.mjs (synthetic grid, real MVT),
// so the figure is the browser's cost; PostGIS tile generation is measured in bench/.
// Prints figures and ends with one JSON line.
// With --server, the same measurement runs against the real server (FIELDRX_URL,
// demo credentials): it creates a ~100k-cell field, plan and uniform prescription
// through the API (PostGIS ST_AsMVT tiles, overview bins at low zoom), then opens it.
// Usage: node tests/e2e/perf_grid.mjs [--cells N] [--runs R] [--server]
//        (needs `npm run build` in frontend/)
import { existsSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, BASE_URL, ROOT, api, apiLogin, launch, EMAIL, PASSWORD } from './lib.mjs';
import { startGridServer, syntheticGrid } from './gridserver.mjs';

const arg = (name, dflt) => {
  const i = process.argv.indexOf(`--${name}`);
  return i >= 0 ? Number(process.argv[i + 1]) : dflt;
};
const cells = arg('cells', 100_000);
const runs = arg('runs', 3);
if (!existsSync(join(ROOT, 'frontend', 'dist', 'index.html'))) {
  console.error('frontend/dist missing: run `npm run build` in frontend/ first');
  process.exit(2);
}
const useServer = process.argv.includes('--server');
const swaths = 200;
let srv;
let rxId = 1;
let email = 'bench@example.org';
let password = 'x';
let nCells;
if (useServer) {
  const token = await apiLogin();
  email = EMAIL;
  password = PASSWORD;
  // A square field of cells * 60 m² (12 m swaths x 5 m cells) well away from other fields.
  const side = Math.sqrt(cells * 60 * 1.03);
  const lat0 = -33.9;
  const lon0 = 18.4 + Math.random() * 0.5;
  const dLat = side / 111_195;
  const dLon = side / (111_195 * Math.cos((lat0 * Math.PI) / 180));
  const ring = [[lon0, lat0], [lon0 + dLon, lat0], [lon0 + dLon, lat0 + dLat], [lon0, lat0 + dLat], [lon0, lat0]];
  const t0 = performance.now();
  const f = await api(token, 'POST', '/fields', {
    type: 'Feature',
    geometry: { type: 'Polygon', coordinates: [ring] },
    properties: { name: `perf ${cells} cells ${Date.now()}` },
  });
  if (!f.ok) throw new Error(`field: ${f.status} ${JSON.stringify(f.data)}`);
  const fieldId = f.data.properties?.id ?? f.data.id;
  const p = await api(token, 'POST', `/fields/${fieldId}/plans`, { swath_width_m: 12, cell_length_m: 5, heading: 'longest_edge', headland_passes: 0 });
  if (!p.ok) throw new Error(`plan: ${p.status} ${JSON.stringify(p.data)}`);
  const rx = await api(token, 'POST', `/plans/${p.data.id}/prescriptions`, { model: 'uniform', params: { rate_kg_ha: 300 } });
  if (!rx.ok) throw new Error(`prescription: ${rx.status} ${JSON.stringify(rx.data)}`);
  rxId = rx.data.id;
  nCells = p.data.n_cells;
  console.log(`server: field ${fieldId}, plan ${p.data.id} (${nCells} cells), prescription ${rxId}; set-up ${((performance.now() - t0) / 1000).toFixed(1)} s`);
  srv = { url: BASE_URL, stats: { tiles: NaN, bytes: NaN }, close: async () => {} };
} else {
  const grid = syntheticGrid({ swaths, cellsPerSwath: Math.ceil(cells / swaths) });
  srv = await startGridServer({ grid });
  nCells = grid.features.length;
}
const b = await launch({ width: 1280, height: 800 });
const { page } = b;
const times = [];
let rendered = 0;
let features = 0;
let binned = 0;
try {
  await page.goto(`${srv.url}/#/login`);
  await page.fill('[data-testid=login-email]', email);
  await page.fill('[data-testid=login-password]', password);
  await page.click('[data-testid=login-submit]');
  await page.waitForSelector('[data-testid=current-user]');
  for (let i = 0; i < runs; i++) {
    // Fresh page load each run: nothing cached in the map (the HTTP cache is off for these responses).
    await page.goto('about:blank');
    await page.goto(`${srv.url}/#/prescriptions/${rxId}`);
    const ms = await page.waitForFunction(() => window.__fieldrxPerf?.rx?.idleMs ?? null, null, { timeout: 120_000 });
    times.push(await ms.jsonValue());
    // Cells drawn: distinct features, counting an overview bin as the n_cells it stands for.
    rendered = await page.evaluate(() => {
      const map = window.__fieldrxMaps.rx;
      const seen = new Map();
      for (const f of map.queryRenderedFeatures({ layers: ['rx-fill'] })) seen.set(f.properties.seq, Number(f.properties.n_cells ?? 1));
      let n = 0;
      let binned = 0;
      for (const v of seen.values()) {
        n += v;
        if (v > 1) binned++;
      }
      return { n, features: seen.size, binned };
    });
    features = rendered.features;
    binned = rendered.binned;
    rendered = rendered.n;
    console.log(`run ${i + 1}: ${times[i].toFixed(0)} ms to idle, ${rendered} cells rendered as ${features} features (${binned} overview bins), zoom ${await page.evaluate(() => window.__fieldrxMaps.rx.getZoom().toFixed(2))}`);
  }
  await page.screenshot({ path: join(ARTIFACTS, 'perf-grid.png') });
} finally {
  await b.close();
  await srv.close();
}
const sorted = [...times].sort((a, c) => a - c);
const median = sorted[Math.floor(sorted.length / 2)];
if (!useServer) console.log(`cells ${nCells}, tiles served ${srv.stats.tiles} (${(srv.stats.bytes / 1e6).toFixed(1)} MB)`);
console.log(`first run ${times[0].toFixed(0)} ms, median ${median.toFixed(0)} ms (target < 3000 ms)`);
console.log(
  JSON.stringify({
    bench: 'ui_grid_render',
    source: useServer ? 'server' : 'synthetic',
    cells: nCells,
    rendered_cells: rendered,
    features,
    overview_bins: binned,
    first_ms: Math.round(times[0]),
    median_ms: Math.round(median),
    runs,
    target_ms: 3000,
    ok: median < 3000 && rendered === nCells,
  }),
);
