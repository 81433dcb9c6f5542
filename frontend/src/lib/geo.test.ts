import { describe, expect, it } from 'vitest';
import {
  bboxOf,
  bearingDeg,
  closeRing,
  geodesicAreaM2,
  pointInRing,
  selfIntersection,
  withHoles,
  type PolygonGeom,
} from './geo';

// A ~100 m x ~100 m square near 52°N: 0.0009° lat ≈ 100 m; lon scaled by cos(52°).
const dLat = 100 / 111_195;
const dLon = 100 / (111_195 * Math.cos((52 * Math.PI) / 180));
const sq: PolygonGeom = {
  type: 'Polygon',
  coordinates: [
    [
      [10, 52],
      [10 + dLon, 52],
      [10 + dLon, 52 + dLat],
      [10, 52 + dLat],
      [10, 52],
    ],
  ],
};

describe('geodesic area', () => {
  it('a 100 m square is about 1 ha', () => {
    expect(geodesicAreaM2(sq) / 10_000).toBeCloseTo(1, 2);
  });
  it('a hole subtracts its area', () => {
    const c = [10 + dLon / 2, 52 + dLat / 2];
    const h = 0.25;
    const hole: [number, number][] = [
      [c[0] - dLon * h, c[1] - dLat * h],
      [c[0] + dLon * h, c[1] - dLat * h],
      [c[0] + dLon * h, c[1] + dLat * h],
      [c[0] - dLon * h, c[1] + dLat * h],
    ];
    const g = withHoles(sq, [hole]);
    expect(g.coordinates).toHaveLength(2);
    expect(geodesicAreaM2(g) / geodesicAreaM2(sq)).toBeCloseTo(0.75, 2);
  });
  it('holes outside the shell are dropped', () => {
    const g = withHoles(sq, [[[0, 0], [0.001, 0], [0.001, 0.001]]]);
    expect(g.coordinates).toHaveLength(1);
  });
  it('empty geometry has zero area', () => {
    expect(geodesicAreaM2(null)).toBe(0);
  });
});

describe('rings', () => {
  it('closes an open ring once', () => {
    const r = closeRing([[0, 0], [1, 0], [1, 1]]);
    expect(r).toHaveLength(4);
    expect(closeRing(r)).toHaveLength(4);
  });
  it('point in ring', () => {
    expect(pointInRing([10 + dLon / 2, 52 + dLat / 2], sq.coordinates[0])).toBe(true);
    expect(pointInRing([9, 52], sq.coordinates[0])).toBe(false);
  });
  it('finds the crossing of a bow-tie and accepts a square', () => {
    const bow: [number, number][] = [[0, 0], [2, 2], [2, 0], [0, 2], [0, 0]];
    expect(selfIntersection(bow)).toEqual([1, 1]);
    expect(selfIntersection(sq.coordinates[0])).toBeNull();
  });
});

describe('bbox and bearing', () => {
  it('bbox over a feature collection', () => {
    const fc = {
      type: 'FeatureCollection',
      features: [
        { type: 'Feature', geometry: { type: 'Point', coordinates: [1, 2] } },
        { type: 'Feature', geometry: { type: 'LineString', coordinates: [[-1, 5], [3, 0]] } },
      ],
    };
    expect(bboxOf(fc)).toEqual([-1, 0, 3, 5]);
    expect(bboxOf({ type: 'FeatureCollection', features: [] })).toBeNull();
  });
  it('bearing north, east, south-west', () => {
    expect(bearingDeg([0, 0], [0, 1])).toBeCloseTo(0);
    expect(bearingDeg([0, 0], [1, 0])).toBeCloseTo(90);
    expect(bearingDeg([0, 0], [-1, -1])).toBeCloseTo(225, 0);
  });
});
