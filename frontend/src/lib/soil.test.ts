import { describe, expect, it } from 'vitest';
import { samplePopup, soilColoring } from './soil';

const fc = (rows: Record<string, unknown>[]) =>
  ({
    type: 'FeatureCollection',
    total: rows.length,
    features: rows.map((p, i) => ({ type: 'Feature', id: i, geometry: { type: 'Point', coordinates: [0, 0] }, properties: { id: i, ...p } })),
  }) as never;

describe('soilColoring', () => {
  it('colours by nitrogen unless another numeric column is chosen', () => {
    const soil = fc([
      { sample_id: 'a', n_mg_kg: 10, ph: 6, import_id: 1 },
      { sample_id: 'b', n_mg_kg: 30, ph: 7, import_id: 1 },
    ]);
    expect(soilColoring(soil, '').key).toBe('n_mg_kg');
    expect(soilColoring(soil, 'ph').key).toBe('ph');
    expect(soilColoring(soil, 'sample_id').key).toBe('n_mg_kg');
    expect(soilColoring(soil, '').sampleKeys).not.toContain('import_id');
  });
  it('no samples: nothing to colour by', () => {
    expect(soilColoring(null, '').key).toBe('');
  });
});

describe('samplePopup', () => {
  it('escapes the values', () => {
    expect(samplePopup({ sample_id: '<b>x</b>', id: 3 })).toBe('<table class="popup"><tr><th>sample_id</th><td>&#60;b&#62;x&#60;/b&#62;</td></tr></table>');
  });
});
