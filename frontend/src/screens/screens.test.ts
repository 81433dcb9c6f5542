/**
 * The acceptance test: "No screen keeps more than ~8 pieces of local state; no screen adds map
 * layers directly." Screens compose overlay components (src/map/overlays) and read data
 * through the hooks of src/api/hooks.ts; these checks keep it that way.
 */
import { readdirSync, readFileSync } from 'node:fs';
import { join } from 'node:path';
import { describe, expect, it } from 'vitest';

/** Screens and the components they are built from: the same two rules hold for both. */
const read = (dir: string) =>
  readdirSync(dir)
    .filter((f) => f.endsWith('.tsx'))
    .map((f) => ({ name: f.replace(/\.tsx$/, ''), src: readFileSync(join(dir, f), 'utf8') }));
const screens = [...read(join(__dirname)), ...read(join(__dirname, '..', 'components'))];

/** Direct map calls a screen must leave to the overlay components. */
const DIRECT_MAP = /\.(addLayer|addSource|removeLayer|removeSource)\(|new\s+maplibregl\.Map\b|\b(replaceVectorSource|addRouteLayers|setGeoJSON)\(/g;
export const MAX_STATE = 8;

describe('screens', () => {
  it('finds the screens', () => {
    expect(screens.map((s) => s.name)).toContain('Fields');
  });

  it('no screen adds or removes map sources/layers or creates a map itself', () => {
    const offenders = screens
      .map((s) => ({ name: s.name, calls: [...s.src.matchAll(DIRECT_MAP)].map((m) => m[0]) }))
      .filter((o) => o.calls.length);
    expect(offenders, 'compose overlay components from src/map/overlays instead').toEqual([]);
  });

  it(`no screen keeps more than ${MAX_STATE} useState calls`, () => {
    const counts = screens.map((s) => ({ name: s.name, n: (s.src.match(/\buseState\s*[<(]/g) ?? []).length }));
    const over = counts.filter((c) => c.n > MAX_STATE);
    expect(over, 'derive from the data hooks (src/api/hooks.ts) or group related fields').toEqual([]);
  });
});
