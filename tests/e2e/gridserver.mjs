// A stand-in server for the render benchmark: serves frontend/dist plus just
// enough of /api/v1 for the prescription screen, and real Mapbox Vector Tiles
// (geojson-vt + vt-pbf, layer "cells", props seq, swath, rate_kg_ha, flag) for a
// synthetic grid. It isolates the browser's rendering cost from the database.
import { createServer } from 'node:http';
import { readFileSync, existsSync, statSync } from 'node:fs';
import { extname, join, normalize } from 'node:path';
import { createRequire } from 'node:module';
import { ROOT } from './lib.mjs';

const require = createRequire(join(ROOT, 'frontend', 'package.json'));
const vtpbf = require('vt-pbf');
const geojsonvt = (await import(join(ROOT, 'frontend', 'node_modules', 'geojson-vt', 'src', 'index.js'))).default;

const M_PER_DEG_LAT = 111_195;

/** swaths x cellsPerSwath rectangles (width x length metres) in boustrophedon path order. */
export function syntheticGrid({ swaths = 200, cellsPerSwath = 500, width = 12, length = 5, lon0 = 10, lat0 = 52 } = {}) {
  const mLon = M_PER_DEG_LAT * Math.cos((lat0 * Math.PI) / 180);
  const features = [];
  let seq = 0;
  for (let s = 0; s < swaths; s++) {
    for (let k = 0; k < cellsPerSwath; k++) {
      const c = s % 2 === 0 ? k : cellsPerSwath - 1 - k;
      const x0 = lon0 + (s * width) / mLon;
      const x1 = lon0 + ((s + 1) * width) / mLon;
      const y0 = lat0 + (c * length) / M_PER_DEG_LAT;
      const y1 = lat0 + ((c + 1) * length) / M_PER_DEG_LAT;
      const rate = 150 + 100 * Math.sin(s / 17) * Math.cos(c / 29) + 0.2 * (s % 50);
      features.push({
        type: 'Feature',
        properties: { seq, swath: s, rate_kg_ha: Math.round(rate * 10) / 10, flag: rate < 70 ? 'clamped_low' : '' },
        geometry: { type: 'Polygon', coordinates: [[[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]]] },
      });
      seq++;
    }
  }
  const bbox = [lon0, lat0, lon0 + (swaths * width) / mLon, lat0 + (cellsPerSwath * length) / M_PER_DEG_LAT];
  return { type: 'FeatureCollection', features, bbox };
}

const TYPES = { '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript', '.css': 'text/css', '.svg': 'image/svg+xml' };

export async function startGridServer({ port = 0, grid = syntheticGrid() } = {}) {
  const index = new geojsonvt(grid, { maxZoom: 16, indexMaxZoom: 5, tolerance: 0.5, buffer: 16, extent: 4096 });
  const [w, s, e, n] = grid.bbox;
  // Cut every tile over the grid once up front so the timed runs measure the
  // browser, not geojson-vt's lazy tiling in this stand-in server.
  const lon2x = (lon, z) => Math.floor(((lon + 180) / 360) * 2 ** z);
  const lat2y = (lat, z) => {
    const r = (lat * Math.PI) / 180;
    return Math.floor(((1 - Math.log(Math.tan(r) + 1 / Math.cos(r)) / Math.PI) / 2) * 2 ** z);
  };
  for (let z = 8; z <= 15; z++)
    for (let x = lon2x(w, z); x <= lon2x(e, z); x++)
      for (let y = lat2y(n, z); y <= lat2y(s, z); y++) index.getTile(z, x, y);
  const boundary = {
    type: 'Feature',
    properties: { id: 1, name: 'Benchmark field', farm_id: 1, area_m2: grid.features.length * 60 },
    geometry: { type: 'MultiPolygon', coordinates: [[[[w, s], [e, s], [e, n], [w, n], [w, s]]]] },
  };
  const json = (res, code, body) => {
    res.writeHead(code, { 'Content-Type': 'application/json' });
    res.end(JSON.stringify(body));
  };
  const dist = join(ROOT, 'frontend', 'dist');
  const stats = { tiles: 0, bytes: 0 };
  const server = createServer((req, res) => {
    const url = new URL(req.url, 'http://x');
    const p = url.pathname;
    let m;
    if (p === '/api/v1/auth/login') return json(res, 200, { access_token: 'bench', token_type: 'bearer', user: { email: 'bench@x' }, organisation: { id: 1, name: 'Bench' } });
    if ((m = p.match(/^\/api\/v1\/tiles\/prescriptions\/1\/1\/(\d+)\/(\d+)\/(\d+)\.mvt$/))) {
      if (req.headers.authorization !== 'Bearer bench') return json(res, 401, { detail: 'no token' });
      const tile = index.getTile(+m[1], +m[2], +m[3]);
      if (!tile) {
        res.writeHead(204);
        return res.end();
      }
      const buf = Buffer.from(vtpbf.fromGeojsonVt({ cells: tile }, { version: 2 }));
      stats.tiles++;
      stats.bytes += buf.length;
      res.writeHead(200, { 'Content-Type': 'application/vnd.mapbox-vector-tile', 'Cache-Control': 'no-store' });
      return res.end(buf);
    }
    // The few answers the prescription screen reads, in the server's shapes (PrescriptionOut, ...).
    if (p === '/api/v1/prescriptions/1')
      return json(res, 200, {
        id: 1,
        plan_id: 1,
        model: 'synthetic',
        current_version: 1,
        versions: [{ version: 1, note: '', created_at: null }],
        summary: { n_cells: grid.features.length },
        stats: { out_of_meter_range_count: 0, no_data_count: 0, attention_count: 0, attention_area_m2: 0 },
      });
    if (p === '/api/v1/plans/1') return json(res, 200, { id: 1, field_id: 1 });
    if (p === '/api/v1/fields/1') return json(res, 200, boundary);
    if (p === '/api/v1/machines' || p === '/api/v1/farms') return json(res, 200, { items: [], total: 0 });
    if (p.startsWith('/api/')) return json(res, 404, { detail: 'Not Found' });
    const file = normalize(join(dist, p === '/' ? 'index.html' : p));
    if (!file.startsWith(dist) || !existsSync(file) || !statSync(file).isFile()) return json(res, 404, { detail: 'Not Found' });
    res.writeHead(200, { 'Content-Type': TYPES[extname(file)] ?? 'application/octet-stream' });
    res.end(readFileSync(file));
  });
  await new Promise((r) => server.listen(port, '127.0.0.1', r));
  const url = `http://127.0.0.1:${server.address().port}`;
  return { url, stats, cells: grid.features.length, close: () => new Promise((r) => server.close(r)) };
}
