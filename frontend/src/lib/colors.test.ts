import { describe, expect, it } from 'vitest';
import {
  ACCURACY_BREAKS,
  RED_GREEN,
  classColors,
  classify,
  equalIntervalBreaks,
  histogram,
  legendBreaks,
  legendEntries,
  niceBreaks,
  niceStep,
  quantileBreaks,
  rampColor,
  statusColor,
  stepExpression,
  symmetricBreaks,
  VIRIDIS,
} from './colors';

describe('rampColor', () => {
  it('hits the end stops exactly', () => {
    expect(rampColor(0)).toBe('#440154');
    expect(rampColor(1)).toBe('#fde725');
  });
  it('clamps out-of-range and NaN input', () => {
    expect(rampColor(-3)).toBe(rampColor(0));
    expect(rampColor(7)).toBe(rampColor(1));
    expect(rampColor(Number.NaN)).toBe(rampColor(0));
  });
  it('interpolates halfway between two stops', () => {
    const two: [number, number, number][] = [
      [0, 0, 0],
      [200, 100, 50],
    ];
    expect(rampColor(0.5, two)).toBe('#643219');
  });
  it('middle of viridis is the middle stop', () => {
    expect(rampColor(0.5, VIRIDIS)).toBe('#21918c');
  });
});

describe('breaks', () => {
  it('equal interval covers min..max with n classes', () => {
    expect(equalIntervalBreaks(100, 200, 4)).toEqual([100, 125, 150, 175, 200]);
  });
  it('swaps reversed bounds and widens a degenerate range', () => {
    expect(equalIntervalBreaks(10, 0, 2)).toEqual([0, 5, 10]);
    expect(equalIntervalBreaks(5, 5, 1)).toEqual([4.5, 5.5]);
  });
  it('rejects zero classes', () => {
    expect(() => equalIntervalBreaks(0, 1, 0)).toThrow(RangeError);
  });
  it('nice breaks are round and enclose the data', () => {
    const b = niceBreaks(93.2, 187.9, 5);
    expect(b[0]).toBeLessThanOrEqual(93.2);
    expect(b[b.length - 1]).toBeGreaterThanOrEqual(187.9);
    expect(b).toEqual([80, 100, 120, 140, 160, 180, 200]);
  });
  it('niceStep picks 1/2/2.5/5 x 10^k', () => {
    expect(niceStep(0.13)).toBe(0.2);
    expect(niceStep(23)).toBe(25);
    expect(niceStep(70)).toBe(100);
    expect(niceStep(0)).toBe(1);
  });
  it('quantile breaks split skewed data evenly', () => {
    const vals = [1, 1, 1, 1, 2, 3, 4, 100];
    const b = quantileBreaks(vals, 2);
    expect(b[0]).toBe(1);
    expect(b[b.length - 1]).toBe(100);
    const h = histogram(vals, b);
    expect(h.reduce((a, c) => a + c, 0)).toBe(vals.length);
  });
  it('quantile breaks collapse duplicates and survive constant data', () => {
    expect(quantileBreaks([3, 3, 3], 4)).toEqual([2.5, 3.5]);
    expect(quantileBreaks([], 3)).toEqual([0, 1]);
  });
  it('symmetric breaks are centred on zero', () => {
    expect(symmetricBreaks(10, 4)).toEqual([-10, -5, 0, 5, 10]);
    expect(symmetricBreaks(0, 2)).toEqual([-1, 0, 1]);
  });
});

describe('classify / histogram / legend / expression agree', () => {
  const breaks = [0, 10, 20, 30];
  it('classifies boundaries into the upper class, extremes into end classes', () => {
    expect(classify(-5, breaks)).toBe(0);
    expect(classify(0, breaks)).toBe(0);
    expect(classify(9.99, breaks)).toBe(0);
    expect(classify(10, breaks)).toBe(1);
    expect(classify(30, breaks)).toBe(2);
    expect(classify(99, breaks)).toBe(2);
  });
  it('histogram counts per class and ignores NaN', () => {
    expect(histogram([1, 5, 12, 25, 29, 30, Number.NaN], breaks)).toEqual([2, 1, 3]);
  });
  it('legend labels use the formatter and need one colour per class', () => {
    const cols = classColors(3);
    const e = legendEntries(breaks, cols, (v) => `${v}`);
    expect(e.map((x) => x.label)).toEqual(['0 – 10', '10 – 20', '20 – 30']);
    expect(e[2].color).toBe(cols[2]);
    expect(() => legendEntries(breaks, cols.slice(1))).toThrow(RangeError);
  });
  it('step expression has the same thresholds as classify', () => {
    const cols = ['#a', '#b', '#c'];
    expect(stepExpression('rate_kg_ha', breaks, cols)).toEqual([
      'step',
      ['to-number', ['get', 'rate_kg_ha'], 0],
      '#a',
      10,
      '#b',
      20,
      '#c',
    ]);
  });
  it('a single class (uniform rate) is a constant colour, not a step without stops', () => {
    expect(stepExpression('rate_kg_ha', [299.5, 300.5], ['#abc'])).toBe('#abc');
  });
  it('class colours run from the low to the high end of the ramp', () => {
    const c = classColors(5);
    expect(c[0]).toBe('#440154');
    expect(c[4]).toBe('#fde725');
    expect(classColors(0)).toEqual([]);
    expect(classColors(1)).toHaveLength(1);
  });
});

describe('accuracy classes', () => {
  it('100 % falls in the top (green) class and 85 % in the second', () => {
    expect(classify(100, ACCURACY_BREAKS)).toBe(4);
    expect(classify(85, ACCURACY_BREAKS)).toBe(1);
    expect(classColors(5, RED_GREEN)[4]).toBe('#1a9850');
  });
});

describe('statusColor', () => {
  it('distinguishes working, idle, alarm and unknown', () => {
    const set = new Set(['working', 'idle', 'alarm', 'offline'].map(statusColor));
    expect(set.size).toBe(4);
    expect(statusColor(undefined)).toBe(statusColor('offline'));
  });
});

describe('legend of a narrow or constant range', () => {
  const fmt0 = (v: number) => v.toFixed(0);
  const labels = (b: number[], fmt: (v: number) => string) => legendEntries(b, classColors(b.length - 1), fmt).map((e) => e.label);
  it('a constant range is one class labelled with its value', () => {
    // a seeding report at a constant 30 mm read "30 – 30" three times
    const b = legendBreaks(30, 30, 6, 0);
    expect(labels(b, fmt0)).toEqual(['30']);
    expect(stepExpression('v', b, classColors(1))).toBe(classColors(1)[0]);
  });
  it('a range that reads as one value at the precision shown is one class', () => {
    expect(labels(legendBreaks(29.8, 30.2, 6, 0), fmt0)).toEqual(['30']);
    expect(labels(legendBreaks(0.412, 0.414, 6, 2), (v) => v.toFixed(2))).toEqual(['0.41']);
  });
  it('a narrow range gets classes no finer than its labels tell apart', () => {
    const l = labels(legendBreaks(29.6, 31.2, 6, 0), fmt0);
    expect(new Set(l).size).toBe(l.length);
    expect(l).toEqual(['29 – 30', '30 – 31', '31 – 32']);
  });
  it('a wide range keeps nice equal classes', () => {
    expect(legendBreaks(93.2, 187.9, 5, 0)).toEqual(niceBreaks(93.2, 187.9, 5));
  });
  it('a class whose ends read the same is labelled once', () => {
    expect(labels([30, 30.2, 31], fmt0)).toEqual(['30', '30 – 31']);
  });
});
