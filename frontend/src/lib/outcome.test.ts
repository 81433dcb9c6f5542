import { describe, expect, it } from 'vitest';
import { outcomeRows, utcMinute } from './outcome';

describe('outcome', () => {
  it('leads with target vs applied and the difference, over-application signed +', () => {
    const rows = outcomeRows({
      target_kg: 25,
      applied_kg: 34.4,
      target_kg_ha: 250,
      applied_kg_ha: 344,
      difference_pct: 37.6,
      under_area_pct: 0,
      over_area_pct: 92.5,
      tolerance_pct: 10,
    });
    expect(rows[0][0]).toBe('Target → applied');
    expect(rows[0][1]).toContain('+37.6 %');
    expect(rows[0][1]).toContain('250');
    expect(rows[0][1]).toContain('344');
    expect(rows[1]).toEqual(['Area under / over by > 10 %', '0.0 % / 92.5 %', 'report-outcome-share']);
  });
  it('under-application is signed −, and no outcome gives no rows', () => {
    expect(outcomeRows({ target_kg: 10, applied_kg: 9, difference_pct: -10 })[0][1]).toContain('−10.0 %');
    expect(outcomeRows(null)).toEqual([]);
    expect(outcomeRows({})).toEqual([]);
  });
  it('dates from ISO text or epoch seconds', () => {
    expect(utcMinute('2026-11-28T07:02:31Z')).toBe('2026-11-28 07:02 UTC');
    expect(utcMinute(0)).toBe('1970-01-01 00:00 UTC');
    expect(utcMinute(null)).toBe('–');
  });
});
