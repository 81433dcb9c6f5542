import { describe, expect, it } from 'vitest';
import { decimate, indexAtTime, normaliseTrack, toUnixSeconds } from './track';

describe('track normalisation', () => {
  it('reads arrays, {items} and GeoJSON points, sorted by time', () => {
    const a = normaliseTrack([
      { t: 20, lon: 1, lat: 2, speed_raw_m_s: 2.1 },
      { t: 10, lon: 1, lat: 2 },
    ]);
    expect(a.map((p) => p.t)).toEqual([10, 20]);
    expect(a[1].speed_raw_m_s).toBe(2.1);
    expect(normaliseTrack({ items: [{ t: 1 }] })).toHaveLength(1);
    const g = normaliseTrack({
      type: 'FeatureCollection',
      features: [{ type: 'Feature', geometry: { type: 'Point', coordinates: [5, 6] }, properties: { t: '2026-01-01T00:00:00Z' } }],
    });
    expect(g[0].lon).toBe(5);
    expect(g[0].t).toBe(Date.parse('2026-01-01T00:00:00Z') / 1000);
  });
  it('drops rows without a time and maps missing values to null', () => {
    const a = normaliseTrack([{ lon: 1 }, { t: 5, actual_shaft_rpm: '' }]);
    expect(a).toHaveLength(1);
    expect(a[0].actual_shaft_rpm).toBeNull();
  });
  it('epoch milliseconds become seconds', () => {
    expect(toUnixSeconds(1_700_000_000_000)).toBe(1_700_000_000);
    expect(toUnixSeconds('nope')).toBeNull();
  });
});

describe('replay helpers', () => {
  const pts = [{ t: 0 }, { t: 10 }, { t: 20 }, { t: 30 }];
  it('index at time is the last point not after t', () => {
    expect(indexAtTime(pts, -1)).toBe(-1);
    expect(indexAtTime(pts, 0)).toBe(0);
    expect(indexAtTime(pts, 15)).toBe(1);
    expect(indexAtTime(pts, 30)).toBe(3);
    expect(indexAtTime(pts, 99)).toBe(3);
    expect(indexAtTime([], 5)).toBe(-1);
  });
  it('decimate keeps the ends and the count', () => {
    const xs = Array.from({ length: 101 }, (_, i) => i);
    const d = decimate(xs, 11);
    expect(d).toHaveLength(11);
    expect(d[0]).toBe(0);
    expect(d[10]).toBe(100);
    expect(decimate([1, 2], 10)).toEqual([1, 2]);
  });
});
