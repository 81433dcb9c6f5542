import { describe, expect, it } from 'vitest';
import { addTrailPoint, trailSegments, type TrailPoint } from './trail';

// ~1 m in degrees at the equator
const M = 1 / 111_195;

describe('trail', () => {
  it('keeps positions in time order whatever order they arrive in', () => {
    const tr: TrailPoint[] = [];
    for (const t of [1, 3, 2, 5, 4, 3]) addTrailPoint(tr, { lon: t * M, lat: 0, t }, 10);
    expect(tr.map((p) => p.t)).toEqual([1, 2, 3, 4, 5]);
    addTrailPoint(tr, { lon: 0, lat: 0, t: 6 }, 3);
    expect(tr.map((p) => p.t)).toEqual([4, 5, 6]);
  });

  it('draws one continuous drive as one line', () => {
    const tr = Array.from({ length: 20 }, (_, i) => ({ lon: i * 3 * M, lat: 0, t: i }));
    const segs = trailSegments(tr);
    expect(segs).toHaveLength(1);
    expect(segs[0]).toHaveLength(20);
  });

  it('does not join passes: a reversal, a jump or a gap in time starts a new line', () => {
    // east along y=0, then (sampled sparsely across the headland turn) west along y=12 m
    const east = Array.from({ length: 5 }, (_, i) => ({ lon: i * 3 * M, lat: 0, t: i }));
    const west = Array.from({ length: 5 }, (_, i) => ({ lon: (12 - i * 3) * M, lat: 12 * M, t: 5 + i }));
    const passes = trailSegments([...east, ...west]);
    expect(passes).toHaveLength(2);
    // no line across the swaths: each pass keeps to its own latitude
    expect(passes.map((s) => new Set(s.map((p) => Math.round(p[1] / M))))).toEqual([new Set([0]), new Set([12])]);
    // a 100 m jump in one second
    const jump = [...east, { lon: 112 * M, lat: 0, t: 5 }, { lon: 115 * M, lat: 0, t: 6 }];
    expect(trailSegments(jump)).toHaveLength(2);
    // the same place again after a minute's silence
    const gap = [...east, { lon: 15 * M, lat: 0, t: 70 }, { lon: 18 * M, lat: 0, t: 71 }];
    expect(trailSegments(gap)).toHaveLength(2);
  });

  it('keeps a gradual headland turn in one line', () => {
    // a half circle of radius 6 m sampled every 15 degrees, one sample a second
    const arc = Array.from({ length: 13 }, (_, i) => {
      const a = (i * 15 * Math.PI) / 180;
      return { lon: 6 * Math.sin(a) * M, lat: (6 - 6 * Math.cos(a)) * M, t: i };
    });
    expect(trailSegments(arc)).toHaveLength(1);
  });
});
