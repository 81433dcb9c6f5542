import { describe, expect, it } from 'vitest';
import { attentionLines, attentionOf, attentionSummary, flaggedConfirmation } from './flags';

const RX = {
  fallback_rate_kg_ha: 650,
  summary: {
    flagged: { no_data: 3, below_meter_range: 10, above_meter_range: 2, manual: 1, zone: 0 },
    attention: { count: 15, area_m2: 172.5, seq: [0, 1, 2] },
    meter: { rate_min_kg_ha: 583.63, rate_max_kg_ha: 882.08, speed_min_kmh: 3, speed_max_kmh: 9 },
    interpolation: { method: 'idw', search_distance_m: 50 },
  },
};

describe('flagged cells of a prescription', () => {
  it('reads count, area and cells from the summary', () => {
    const a = attentionOf(RX);
    expect(a.count).toBe(15);
    expect(a.seq).toEqual([0, 1, 2]);
    expect(a.outOfRange).toBe(12);
    expect(attentionSummary(a)).toBe('15 cells (0.017 ha)');
  });
  it('names the limit with its speed and the fallback rate', () => {
    expect(attentionLines(attentionOf(RX))).toEqual([
      '10 below the lowest meterable rate 583.6 kg/ha at 3 km/h',
      '2 above the highest meterable rate 882.1 kg/ha at 9 km/h',
      '3 with no soil sample within 50 m: fallback rate 650.0 kg/ha',
    ]);
  });
  it('an older summary without flags reads as nothing flagged', () => {
    const a = attentionOf({ summary: {} });
    expect(a.count).toBe(0);
    expect(attentionLines(a)).toEqual([]);
  });
});

describe('job confirmation', () => {
  it('recognises the 409 asking to confirm flagged cells', () => {
    const c = flaggedConfirmation(409, {
      detail: 'prescription 4 v2 has 15 cell(s) ...',
      where: 'confirm_flagged',
      flagged: { count: 15, area_m2: 172.5, seq: [0, 1] },
    });
    expect(c).toEqual({ message: 'prescription 4 v2 has 15 cell(s) ...', count: 15, areaM2: 172.5, seq: [0, 1] });
  });
  it('leaves other errors alone', () => {
    expect(flaggedConfirmation(422, { detail: 'width', where: 'machine_id' })).toBeNull();
    expect(flaggedConfirmation(409, { detail: 'final state' })).toBeNull();
  });
});
