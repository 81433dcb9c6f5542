import { describe, expect, it } from 'vitest';
import { cellValue, kindUi } from '../kinds';
import { ndviPreview, ndviRate } from '../kinds/ndvi_topdress';
import { qualifiedBand } from '../kinds/seeding_depth';
import { jobBody, kindLabel, kindList, kindsTaking, planLabel, settingsBody, unitRefusal, type KindInfo, type SettingField } from './jobkinds';

/** What GET /jobs/kinds says of a field (the server's registry is the one list). */
const field = (path: string, dflt: unknown, options: string[] = []): SettingField => ({
  path,
  label: path,
  unit: '',
  default: dflt,
  source: 'seed 000',
  step: null,
  options,
});
const NDVI = [
  field('rate_curve.ndvi_lo', 0.24),
  field('rate_curve.ndvi_hi', 0.65),
  field('window', 15),
  field('controller.name', 'isp', ['isp', 'incremental_pid', 'ladrc']),
  field('restrict_to_boundary', true, ['true', 'false']),
];
const kind = (name: string, rates_from: 'cells' | 'sensors', settings: SettingField[] = []): KindInfo => ({
  name,
  label: `${name} label`,
  noun: name,
  source: 'seed',
  rates_from,
  rate_units: rates_from === 'cells' ? ['kg/ha', 'l/ha'] : [],
  progress: rates_from === 'cells' ? 'cells' : 'work',
  needs: '',
  defaults: {},
  controllers: [],
  settings,
});

describe('job kinds', () => {
  it('sends only what differs from the default', () => {
    expect(settingsBody(NDVI, { 'rate_curve.ndvi_lo': '0.24', window: '15' })).toEqual({});
    expect(settingsBody(NDVI, { 'rate_curve.ndvi_hi': '0.7', window: '9', 'controller.name': 'ladrc' })).toEqual({
      rate_curve: { ndvi_hi: 0.7 },
      window: 9,
      controller: { name: 'ladrc' },
    });
    expect(settingsBody([field('target_depth_mm', 30)], { target_depth_mm: '25' })).toEqual({ target_depth_mm: 25 });
    expect(settingsBody(NDVI, { restrict_to_boundary: 'true' })).toEqual({});
    expect(settingsBody(NDVI, { restrict_to_boundary: 'false' })).toEqual({ restrict_to_boundary: false });
  });

  it('builds the body of each kind from where its rates come from', () => {
    expect(jobBody(kind('rx', 'cells'), { prescriptionId: '3', version: '', machineId: '2' })).toEqual({
      kind: 'rx',
      prescription_id: 3,
      prescription_version: undefined,
      machine_id: 2,
    });
    const depth = kind('depth', 'sensors', [field('target_depth_mm', 30)]);
    expect(jobBody(depth, { planId: '7', machineId: '2' }, { target_depth_mm: '40' })).toEqual({
      kind: 'depth',
      plan_id: 7,
      machine_id: 2,
      settings: { target_depth_mm: 40 },
    });
  });

  it('lists and labels the kinds the server names', () => {
    const kinds = { a: kind('a', 'cells'), b: kind('b', 'sensors') };
    expect(kindList(kinds).map((k) => k.name)).toEqual(['a', 'b']);
    expect(kindLabel(kinds, 'b')).toBe('b label');
    expect(kindLabel(undefined, 'b')).toBe('b');
  });

  it('previews the paper curve, clamped', () => {
    expect(ndviRate(0.24, 0.24, 375, 0.65, 180)).toBe(375);
    expect(ndviRate(0.65, 0.24, 375, 0.65, 180)).toBe(180);
    expect(ndviRate(0.1, 0.24, 375, 0.65, 180)).toBe(375);
    expect(ndviRate(0.445, 0.24, 375, 0.65, 180)).toBeCloseTo(277.5, 6);
    expect(Number.isNaN(ndviRate(0.5, 0.6, 375, 0.5, 180))).toBe(true);
    const p = ndviPreview({});
    expect(p[0]).toEqual({ ndvi: 0.2, rate: 375 });
    expect(p[5]).toEqual({ ndvi: 0.7, rate: 180 });
  });

  it('uses the GB/T 20865 band', () => {
    expect(qualifiedBand(30)).toEqual([20, 40]);
    expect(qualifiedBand(25)).toEqual([20, 30]);
  });

  it('picks the map value per view of each kind module', () => {
    const c = { ndvi: 0.5, applied_rate_kg_ha: 250, depth_mm: 31, qualified_pct: 99 };
    const [ndvi, depth] = ['ndvi_topdress', 'seeding_depth'].map(kindUi);
    expect(cellValue(ndvi, 'ndvi', c)).toBe(0.5);
    expect(cellValue(ndvi, 'rate', c)).toBe(250);
    expect(cellValue(depth, 'depth', c)).toBe(31);
    expect(cellValue(depth, 'qualified', c)).toBe(99);
    expect(cellValue(depth, 'depth', {})).toBeNull();
    expect(cellValue(kindUi('no_module'), 'depth', c)).toBeNull();
  });

  it('names a plan in the picker by its swath, cells and day, not only its number', () => {
    const p = { id: 12, params: { swath_width_m: 3.6, cell_length_m: 5 }, n_cells: 84, created_at: '2026-11-28T10:11:12Z' };
    expect(planLabel(p)).toBe('Plan 12 · 3.6 m swath, 5 m cells · 84 cells · 2026-11-28');
    expect(planLabel({ ...p, created_at: null })).toBe('Plan 12 · 3.6 m swath, 5 m cells · 84 cells');
  });
});

describe("a prescription's unit and the job kinds", () => {
  const kinds = { prescription_map: kind('prescription_map', 'cells'), ndvi_topdress: kind('ndvi_topdress', 'sensors') };
  it('offers only the cells kinds that take the unit', () => {
    expect(kindsTaking(kinds, 'l/ha').map((k) => k.name)).toEqual(['prescription_map']);
    expect(kindsTaking(kinds, 'seeds/ha')).toEqual([]);
  });
  it('says why a kind cannot take it, as the server does', () => {
    expect(unitRefusal(kinds.prescription_map, 7, 'seeds/ha')).toBe('prescription 7 is in seeds/ha: a prescription_map job takes prescriptions in kg/ha or l/ha');
    expect(unitRefusal(kinds.prescription_map, 7, 'kg/ha')).toBeNull();
    expect(unitRefusal(kinds.ndvi_topdress, 7, 'seeds/ha')).toBeNull();
  });
});
