#!/usr/bin/env node
// Time to first full render of a 100,000-cell prescription grid in headless
// Chromium, through the real prescription screen (vector tiles, bearer token via
// transformRequest). Tiles come from gridserver.mjs (synthetic grid, real MVT),
// so the figure is the browser's cost; PostGIS tile generation is measured in bench/.
// Prints figures and ends with one JSON line.
// Usage: node tests/e2e/perf_grid.mjs [--cells N] [--runs R]   (needs `npm run build` in frontend/)
import { existsSync } from 'node:fs';
import { join } from 'node:path';
import { ARTIFACTS, ROOT, launch } from './lib.mjs';
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
const swaths = 200;
const grid = syntheticGrid({ swaths, cellsPerSwath: Math.ceil(cells / swaths) });
const srv = await startGridServer({ grid });
const b = await launch({ width: 1280, height: 800 });
const { page } = b;
const times = [];
let rendered = 0;
try {
  await page.goto(`${srv.url}/#/login`);
  await page.fill('[data-testid=login-email]', 'bench@example.org');
  await page.fill('[data-testid=login-password]', 'x');
  await page.click('[data-testid=login-submit]');
  for (let i = 0; i < runs; i++) {
    // Fresh page load each run: nothing cached in the map (the HTTP cache is off for these responses).
    await page.goto('about:blank');
    await page.goto(`${srv.url}/#/prescriptions/1`);
    const ms = await page.waitForFunction(() => window.__fieldrxPerf?.rx?.idleMs ?? null, null, { timeout: 120_000 });
    times.push(await ms.jsonValue());
    rendered = await page.evaluate(() => {
      const map = window.__fieldrxMaps.rx;
      const seen = new Set();
      for (const f of map.queryRenderedFeatures({ layers: ['rx-fill'] })) seen.add(f.properties.seq);
      return seen.size;
    });
    console.log(`run ${i + 1}: ${times[i].toFixed(0)} ms to idle, ${rendered} distinct cells rendered, zoom ${await page.evaluate(() => window.__fieldrxMaps.rx.getZoom().toFixed(2))}`);
  }
  await page.screenshot({ path: join(ARTIFACTS, 'perf-grid.png') });
} finally {
  await b.close();
  await srv.close();
}
const sorted = [...times].sort((a, c) => a - c);
const median = sorted[Math.floor(sorted.length / 2)];
console.log(`cells ${grid.features.length}, tiles served ${srv.stats.tiles} (${(srv.stats.bytes / 1e6).toFixed(1)} MB)`);
console.log(`first run ${times[0].toFixed(0)} ms, median ${median.toFixed(0)} ms (target < 3000 ms)`);
console.log(JSON.stringify({ bench: 'ui_grid_render', cells: grid.features.length, rendered_cells: rendered, first_ms: Math.round(times[0]), median_ms: Math.round(median), runs, target_ms: 3000, ok: median < 3000 && rendered === grid.features.length }));
