import { describe, expect, it } from 'vitest';
import { cellValue, jobBody, ndviPreview, ndviRate, planLabel, qualifiedBand, settingsBody } from './jobkinds';

describe('job kinds', () => {
  it('sends only what differs from the paper', () => {
    expect(settingsBody('ndvi_topdress', { 'rate_curve.ndvi_lo': '0.24', window: '15' })).toEqual({});
    expect(settingsBody('ndvi_topdress', { 'rate_curve.ndvi_hi': '0.7', window: '9', 'controller.name': 'ladrc' })).toEqual({
      rate_curve: { ndvi_hi: 0.7 },
      window: 9,
      controller: { name: 'ladrc' },
    });
    expect(settingsBody('seeding_depth', { target_depth_mm: '25' })).toEqual({ target_depth_mm: 25 });
    expect(settingsBody('ndvi_topdress', { restrict_to_boundary: 'true' })).toEqual({});
    expect(settingsBody('ndvi_topdress', { restrict_to_boundary: 'false' })).toEqual({ restrict_to_boundary: false });
  });

  it('builds the body of each kind', () => {
    expect(jobBody('prescription_map', { prescriptionId: '3', version: '', machineId: '2' })).toEqual({
      prescription_id: 3,
      prescription_version: undefined,
      machine_id: 2,
    });
    expect(jobBody('seeding_depth', { planId: '7', machineId: '2' }, { target_depth_mm: '40' })).toEqual({
      kind: 'seeding_depth',
      plan_id: 7,
      machine_id: 2,
      settings: { target_depth_mm: 40 },
    });
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

  it('picks the map value per view', () => {
    const c = { ndvi: 0.5, applied_rate_kg_ha: 250, depth_mm: 31, qualified_pct: 99 };
    expect(cellValue('ndvi_topdress', 'ndvi', c)).toBe(0.5);
    expect(cellValue('ndvi_topdress', 'rate', c)).toBe(250);
    expect(cellValue('seeding_depth', 'depth', c)).toBe(31);
    expect(cellValue('seeding_depth', 'qualified', c)).toBe(99);
    expect(cellValue('seeding_depth', 'depth', {})).toBeNull();
  });
  it('names a plan in the picker by its swath, cells and day, not only its number', () => {
    const p = { id: 12, params: { swath_width_m: 3.6, cell_length_m: 5 }, n_cells: 84, created_at: '2026-11-28T10:11:12Z' };
    expect(planLabel(p)).toBe('Plan 12 · 3.6 m swath, 5 m cells · 84 cells · 2026-11-28');
    expect(planLabel({ ...p, created_at: null })).toBe('Plan 12 · 3.6 m swath, 5 m cells · 84 cells');
  });
});
