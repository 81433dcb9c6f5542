import { describe, expect, it } from 'vitest';
import { calibrationText, EMPTY_CALIBRATION, formOf, meterableRange, rateAt, shaftRpmFor, validateCalibration } from './calibration';

const SEED001 = { slope: '237.2', intercept: '-404.4', minRpm: '30', maxRpm: '130', lag: '1.52' };

describe('calibration form', () => {
  it('has no default: an empty form names every missing field', () => {
    const r = validateCalibration(EMPTY_CALIBRATION);
    expect(r.value).toBeUndefined();
    expect(Object.keys(r.errors).sort()).toEqual(['intercept', 'lag', 'maxRpm', 'minRpm', 'slope']);
    expect(r.errors.slope).toMatch(/required/);
  });
  it('accepts seed 001 eq. 1 and builds the API body', () => {
    const r = validateCalibration(SEED001);
    expect(r.errors).toEqual({});
    expect(r.value).toEqual({
      lag_s: 1.52,
      calibration: { kind: 'linear', slope_g_min_per_rpm: 237.2, intercept_g_min: -404.4, min_rpm: 30, max_rpm: 130 },
    });
  });
  it('refuses an inverted shaft range, a zero slope and a floor that meters nothing', () => {
    expect(validateCalibration({ ...SEED001, maxRpm: '20' }).errors.maxRpm).toMatch(/greater than the minimum/);
    expect(validateCalibration({ ...SEED001, slope: '0' }).errors.slope).toMatch(/> 0/);
    expect(validateCalibration({ ...SEED001, minRpm: '1' }).errors.minRpm).toMatch(/raise the minimum/);
    expect(validateCalibration({ ...SEED001, lag: 'x' }).errors.lag).toMatch(/number/);
  });
  it('keeps the seed 001 numbers (docs/science.md)', () => {
    const cal = validateCalibration(SEED001).value!.calibration;
    expect(shaftRpmFor(cal, 750, 2.3, 9 / 3.6)).toBeCloseTo(110.8, 1);
    // the old hidden default on a 12 m machine: at most 169.1 kg/ha at 9 km/h
    expect(rateAt(cal, 130, 12, 2.5)).toBeCloseTo(169.1, 1);
    const [lo, hi] = meterableRange(cal, 2.3, 3 / 3.6, 9 / 3.6);
    expect(lo).toBeCloseTo(583.6, 1);
    expect(hi).toBeCloseTo(882.1, 1);
  });
});

describe('calibration text', () => {
  it('shows the stored calibration in eq. 1 form', () => {
    expect(
      calibrationText({ kind: 'linear', slope_g_min_per_rpm: 237.2, intercept_g_min: -404.4, min_rpm: 30, max_rpm: 130 }),
    ).toBe('q0 = 237.2 r − 404.4 g/min, 30–130 r/min');
    expect(calibrationText(undefined)).toBe('–');
  });
});

describe('editing a stored calibration', () => {
  it('round-trips through the form', () => {
    const stored = { kind: 'linear', slope_g_min_per_rpm: 237.2, intercept_g_min: -404.4, min_rpm: 30, max_rpm: 130 };
    const r = validateCalibration(formOf(stored, 1.52));
    expect(r.value).toEqual({ lag_s: 1.52, calibration: stored });
  });
});
