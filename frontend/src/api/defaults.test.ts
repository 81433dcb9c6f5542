import { readdirSync, readFileSync, statSync } from 'node:fs';
import { join } from 'node:path';
import { describe, expect, it } from 'vitest';
import openapi from './openapi.json';
import { serverDefault } from './defaults';

type Doc = { components: { schemas: Record<string, { properties?: Record<string, { default?: unknown }> }> } };
const doc = openapi as unknown as Doc;
const apiDefault = (model: string, field: string) => doc.components.schemas[model]?.properties?.[field]?.default;

function sources(dir: string): string[] {
  return readdirSync(dir).flatMap((n) => {
    const p = join(dir, n);
    if (statSync(p).isDirectory()) return n === 'generated' ? [] : sources(p);
    return /\.tsx?$/.test(n) && !n.endsWith('.test.ts') ? [p] : [];
  });
}

describe('form defaults are the API\'s (headland 1 vs 0, idw vs cell_mean)', () => {
  it.each([
    ['PlanIn', 'headland_passes'],
    ['PlanIn', 'turn_radius_m'],
    ['PlanIn', 'reverse'],
    ['PlanIn', 'pattern'],
    ['PrescriptionIn', 'interpolation'],
    ['SoilZonesIn', 'interpolation'],
    ['SoilZonesIn', 'k'],
  ] as const)('%s.%s equals the OpenAPI document', (model, field) => {
    expect(apiDefault(model, field)).toBeDefined();
    expect(serverDefault(model, field as never)).toEqual(apiDefault(model, field));
  });

  it('the documented defaults: no headland ring, inverse distance', () => {
    expect(serverDefault('PlanIn', 'headland_passes')).toBe(0);
    expect(serverDefault('PrescriptionIn', 'interpolation')).toBe('idw');
  });

  it('no form keeps its own copy of these defaults', () => {
    const copies: string[] = [];
    for (const f of sources(join(__dirname, '..'))) {
      const text = readFileSync(f, 'utf8');
      for (const m of text.matchAll(/\[(interp\w*|headland\w*|radius|reverse|pattern), set\w+\] = useState(?:<[^>]*>)?\(([^)]*)\)/g)) {
        if (!m[2].includes('serverDefault')) copies.push(`${f}: ${m[0]}`);
      }
    }
    expect(copies).toEqual([]);
  });
});
