import { describe, expect, it } from 'vitest';
import { NO_TARGET, remap, type MappingIn } from './soilMapping';

const base: MappingIn = {
  columns: { sample_id: 'Probe', x: 'Rechtswert', y: 'Hochwert', n: 'Nmin (kg/ha)' },
  units: { n: 'kg/ha' },
  epsg: 25832,
  bulk_density_g_cm3: 1.5,
};

describe('remap', () => {
  it('moves a quantity to another column and frees the old one', () => {
    const m = remap(base, 'N (mg/kg)', 'n');
    expect(m.columns.n).toBe('N (mg/kg)');
    expect(Object.values(m.columns)).not.toContain('Nmin (kg/ha)');
    expect(m.units).toEqual(base.units);
    expect(m.epsg).toBe(25832);
  });
  it('a column feeds one quantity: mapping it again drops its earlier pairing', () => {
    const m = remap(base, 'Rechtswert', 'y');
    expect(m.columns.y).toBe('Rechtswert');
    expect(m.columns.x).toBeUndefined();
  });
  it('"not read" removes the column', () => {
    const m = remap(base, 'Probe', NO_TARGET);
    expect(m.columns.sample_id).toBeUndefined();
    expect(Object.keys(m.columns)).toHaveLength(3);
  });
});
