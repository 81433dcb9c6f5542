import { describe, expect, it } from 'vitest';
import {
  compass,
  formatArea,
  formatDistance,
  formatDuration,
  formatMass,
  formatPercent,
  formatRate,
  formatSpeed,
  kmhToMs,
  msToKmh,
} from './units';

describe('units', () => {
  it('area switches from m² to ha at 0.1 ha', () => {
    expect(formatArea(999)).toBe('999 m²');
    expect(formatArea(123456)).toBe('12.35 ha');
    expect(formatArea(null)).toBe('–');
    expect(formatArea(Number.NaN)).toBe('–');
  });
  it('speed is stored in m/s and shown in km/h', () => {
    expect(msToKmh(2.5)).toBeCloseTo(9);
    expect(kmhToMs(36)).toBeCloseTo(10);
    expect(formatSpeed(2.5)).toBe('9.0 km/h');
  });
  it('rates, masses, distances, percentages', () => {
    expect(formatRate(152.349)).toBe('152.3 kg/ha');
    expect(formatRate(1500, 0)).toBe('1,500 kg/ha');
    expect(formatMass(850.26)).toBe('850.3 kg');
    expect(formatMass(12345)).toBe('12.35 t');
    expect(formatDistance(512.4)).toBe('512 m');
    expect(formatDistance(2512)).toBe('2.51 km');
    expect(formatPercent(0.4234)).toBe('42.3 %');
  });
  it('durations', () => {
    expect(formatDuration(42)).toBe('42 s');
    expect(formatDuration(185)).toBe('3 min 05 s');
    expect(formatDuration(3720)).toBe('1 h 02 min');
    expect(formatDuration(-1)).toBe('–');
  });
  it('compass wraps around north', () => {
    expect(compass(0)).toBe('N');
    expect(compass(359)).toBe('N');
    expect(compass(-90)).toBe('W');
    expect(compass(135)).toBe('SE');
  });
});
