import { describe, expect, it } from 'vitest';
import {
  defaultImagery,
  imageryLabel,
  ndviLegend,
  opacityFromPercent,
  sortNewest,
  startBounds,
  type ImageryItem,
} from './imagery';

const item = (id: number, over: Partial<ImageryItem> = {}): ImageryItem => ({
  id,
  field_id: 1,
  kind: 'orthophoto',
  name: `img${id}`,
  acquired_on: null,
  created_at: `2026-01-0${id}T00:00:00Z`,
  resolution_m: 0.05,
  bounds: [0, 0, 1, 1],
  tiles: `/api/v1/tiles/imagery/${id}/{z}/{x}/{y}.png`,
  ...over,
});

describe('imagery', () => {
  it('sorts by acquisition date, undated last, then upload time', () => {
    const list = [
      item(1, { acquired_on: '2026-05-01' }),
      item(2),
      item(3, { acquired_on: '2026-06-01' }),
      item(4),
    ];
    expect(sortNewest(list).map((i) => i.id)).toEqual([3, 1, 4, 2]);
  });

  it('defaults to the field newest orthophoto, not a newer NDVI or another field', () => {
    const list = [
      item(1, { acquired_on: '2026-05-01' }),
      item(2, { acquired_on: '2026-07-01', kind: 'ndvi' }),
      item(3, { acquired_on: '2026-08-01', field_id: 9 }),
    ];
    expect(defaultImagery(list, 1)?.id).toBe(1);
    expect(defaultImagery(list.filter((i) => i.kind === 'ndvi'), 1)?.id).toBe(2);
    expect(defaultImagery([], 1)).toBeNull();
  });

  it('clamps opacity', () => {
    expect(opacityFromPercent(50)).toBe(0.5);
    expect(opacityFromPercent(-5)).toBe(0);
    expect(opacityFromPercent(250)).toBe(1);
    expect(opacityFromPercent(Number.NaN)).toBe(1);
  });

  it('labels with kind, date and resolution', () => {
    expect(imageryLabel(item(1, { acquired_on: '2026-05-01' }))).toBe('orthophoto 2026-05-01 (5 cm) img1');
    expect(imageryLabel(item(2, { kind: 'ndvi', resolution_m: 10 }))).toBe('ndvi undated (10.0 m) img2');
  });

  it('opens at the fields extent only when it is a real box', () => {
    expect(startBounds([1, 2, 3, 4])).toEqual([1, 2, 3, 4]);
    expect(startBounds(null)).toBeNull();
    expect(startBounds([3, 2, 1, 4])).toBeNull();
    expect(startBounds([Number.NaN, 2, 3, 4])).toBeNull();
  });
});

describe('NDVI legend', () => {
  it('an NDVI or multispectral image has a ramp from red (0) to green (1) with values', () => {
    for (const kind of ['ndvi', 'multispectral'] as const) {
      const l = ndviLegend(kind);
      expect(l).not.toBeNull();
      expect(l!.gradient).toMatch(/^linear-gradient\(to right, #a50026 0%, .* #006837 100%\)$/);
      expect(l!.ticks.map((t) => t.value)).toEqual(['0.00', '0.25', '0.50', '0.75', '1.00']);
      expect(l!.ticks.map((t) => t.pct)).toEqual([0, 25, 50, 75, 100]);
    }
  });
  it('a photo has no NDVI legend', () => {
    expect(ndviLegend('orthophoto')).toBeNull();
    expect(ndviLegend(null)).toBeNull();
  });
});
