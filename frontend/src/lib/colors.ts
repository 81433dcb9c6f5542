/**
 * Colour scales and legend breaks for rate / accuracy maps.
 *
 * Pure functions so the legend, the histogram and the MapLibre paint
 * expression are computed from the same breaks (what the user reads in the
 * legend is exactly what the map draws).
 */

export type RGB = [number, number, number];

/** Perceptually ordered ramp (viridis stops) so low/high rates read without a legend. */
export const VIRIDIS: RGB[] = [
  [68, 1, 84],
  [59, 82, 139],
  [33, 145, 140],
  [94, 201, 98],
  [253, 231, 37],
];

/** Red (poor) to green (good) for accuracy maps. */
export const RED_GREEN: RGB[] = [
  [215, 48, 39],
  [252, 141, 89],
  [254, 224, 139],
  [145, 207, 96],
  [26, 152, 80],
];

/** Accuracy classes in percent (100 = applied exactly the target); most cells sit near the top. */
export const ACCURACY_BREAKS = [0, 80, 90, 95, 98, 100];

/** Diverging red-white-blue ramp for accuracy (applied - target) maps. */
export const DIVERGING: RGB[] = [
  [178, 24, 43],
  [239, 138, 98],
  [247, 247, 247],
  [103, 169, 207],
  [33, 102, 172],
];

export function toHex([r, g, b]: RGB): string {
  const h = (v: number) =>
    Math.max(0, Math.min(255, Math.round(v)))
      .toString(16)
      .padStart(2, '0');
  return `#${h(r)}${h(g)}${h(b)}`;
}

/** Colour at t in [0, 1] along a ramp, linear in RGB between stops; t is clamped. */
export function rampColor(t: number, ramp: RGB[] = VIRIDIS): string {
  if (!Number.isFinite(t)) t = 0;
  const c = Math.max(0, Math.min(1, t));
  const pos = c * (ramp.length - 1);
  const i = Math.min(Math.floor(pos), ramp.length - 2);
  const f = pos - i;
  const a = ramp[i];
  const b = ramp[i + 1];
  return toHex([a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f]);
}

/** n colours evenly spread over the ramp (one per legend class). */
export function classColors(n: number, ramp: RGB[] = VIRIDIS): string[] {
  if (n <= 0) return [];
  if (n === 1) return [rampColor(0.5, ramp)];
  return Array.from({ length: n }, (_, i) => rampColor(i / (n - 1), ramp));
}

/** "Nice" step (1, 2, 2.5, 5 x 10^k) so legend labels are round numbers. */
export function niceStep(raw: number): number {
  if (!(raw > 0) || !Number.isFinite(raw)) return 1;
  const exp = Math.floor(Math.log10(raw));
  const base = 10 ** exp;
  const f = raw / base;
  const nice = f <= 1 ? 1 : f <= 2 ? 2 : f <= 2.5 ? 2.5 : f <= 5 ? 5 : 10;
  return nice * base;
}

/**
 * Class boundaries for n equal classes covering [min, max]: n + 1 ascending values,
 * first == min and last == max. Degenerate ranges get a 1-unit span so the map
 * still has one valid class.
 */
export function equalIntervalBreaks(min: number, max: number, n: number): number[] {
  if (n < 1) throw new RangeError('n must be >= 1');
  if (!Number.isFinite(min) || !Number.isFinite(max)) throw new RangeError('min/max must be finite');
  if (max < min) [min, max] = [max, min];
  if (max === min) {
    min -= 0.5;
    max += 0.5;
  }
  const step = (max - min) / n;
  return Array.from({ length: n + 1 }, (_, i) => (i === n ? max : min + step * i));
}

/** Equal-interval breaks rounded outward to a nice step (legend reads 100, 120, 140 ...). */
export function niceBreaks(min: number, max: number, n: number): number[] {
  if (n < 1) throw new RangeError('n must be >= 1');
  if (max < min) [min, max] = [max, min];
  if (max === min) return equalIntervalBreaks(min, max, 1);
  const step = niceStep((max - min) / n);
  const lo = Math.floor(min / step) * step;
  const hi = Math.ceil(max / step) * step;
  const k = Math.max(1, Math.round((hi - lo) / step));
  return Array.from({ length: k + 1 }, (_, i) => round12(lo + step * i));
}

/**
 * Breaks for a legend read at `decimals` places: nice equal classes, never finer than the
 * labels can tell apart. A range that reads as one value (a constant 30 mm, or 29.8-30.2 at
 * 0 places) is one class from min to max: not several classes all labelled "30 – 30".
 */
export function legendBreaks(min: number, max: number, n: number, decimals: number): number[] {
  if (!Number.isFinite(min) || !Number.isFinite(max)) throw new RangeError('min/max must be finite');
  if (max < min) [min, max] = [max, min];
  const unit = 10 ** -Math.max(0, Math.floor(decimals));
  if (min.toFixed(decimals) === max.toFixed(decimals)) return [min, max];
  const step = Math.max(niceStep((max - min) / n), unit);
  const lo = Math.floor(min / step) * step;
  const hi = Math.ceil(max / step) * step;
  const k = Math.max(1, Math.round((hi - lo) / step));
  return Array.from({ length: k + 1 }, (_, i) => round12(lo + step * i));
}

/** Quantile breaks: each class holds about the same number of cells; duplicates removed. */
export function quantileBreaks(values: number[], n: number): number[] {
  if (n < 1) throw new RangeError('n must be >= 1');
  const v = values.filter(Number.isFinite).sort((a, b) => a - b);
  if (v.length === 0) return equalIntervalBreaks(0, 1, 1);
  const out: number[] = [];
  for (let i = 0; i <= n; i++) {
    const q = (i / n) * (v.length - 1);
    const lo = Math.floor(q);
    const hi = Math.ceil(q);
    const val = v[lo] + (v[hi] - v[lo]) * (q - lo);
    if (out.length === 0 || val > out[out.length - 1]) out.push(val);
  }
  if (out.length === 1) return equalIntervalBreaks(out[0], out[0], 1);
  return out;
}

/** Index of the class holding value (breaks ascending); values outside go to the end classes. */
export function classify(value: number, breaks: number[]): number {
  const n = breaks.length - 1;
  if (n < 1) return 0;
  for (let i = 1; i < n; i++) if (value < breaks[i]) return i - 1;
  return n - 1;
}

export interface LegendEntry {
  color: string;
  from: number;
  to: number;
  label: string;
  /** Drawn as an outline of this colour (a marking over the classes, e.g. edited cells), not a fill. */
  outline?: boolean;
}

export function legendEntries(
  breaks: number[],
  colors: string[],
  fmt: (v: number) => string = (v) => String(v),
): LegendEntry[] {
  const n = breaks.length - 1;
  if (colors.length !== n) throw new RangeError(`need ${n} colours, got ${colors.length}`);
  return Array.from({ length: n }, (_, i) => {
    const [a, b] = [fmt(breaks[i]), fmt(breaks[i + 1])];
    // a class that reads as one value is labelled once ("30", not "30 – 30")
    return { color: colors[i], from: breaks[i], to: breaks[i + 1], label: a === b ? a : `${a} – ${b}` };
  });
}

/**
 * MapLibre `step` expression over a numeric feature property, matching classify():
 * value < breaks[1] -> colors[0], ..., >= breaks[n-1] -> colors[n-1].
 */
export function stepExpression(prop: string, breaks: number[], colors: string[]): unknown[] | string {
  const n = breaks.length - 1;
  if (colors.length !== n) throw new RangeError(`need ${n} colours, got ${colors.length}`);
  // One class (e.g. a uniform rate): MapLibre's step needs at least one stop, so a constant.
  if (n === 1) return colors[0];
  const expr: unknown[] = ['step', ['to-number', ['get', prop], 0], colors[0]];
  for (let i = 1; i < n; i++) expr.push(breaks[i], colors[i]);
  return expr;
}

/** Counts of values per class (same classing as the map). */
export function histogram(values: number[], breaks: number[]): number[] {
  const counts = new Array(Math.max(1, breaks.length - 1)).fill(0);
  for (const v of values) if (Number.isFinite(v)) counts[classify(v, breaks)]++;
  return counts;
}

/** Symmetric breaks around zero for an accuracy (error %) map. */
export function symmetricBreaks(maxAbs: number, n: number): number[] {
  const m = maxAbs > 0 && Number.isFinite(maxAbs) ? maxAbs : 1;
  return equalIntervalBreaks(-m, m, n);
}

function round12(v: number): number {
  return Math.round(v * 1e12) / 1e12;
}

/** Colour for a machine status on the fleet map. */
export function statusColor(status: string | undefined | null): string {
  switch (status) {
    case 'working':
    case 'running':
    case 'applying':
      return '#2e9e44';
    case 'idle':
    case 'paused':
      return '#e0a100';
    case 'alarm':
    case 'alert':
    case 'fault':
      return '#d7263d';
    case 'moving':
    case 'transit':
      return '#2b6cb0';
    default:
      return '#777777';
  }
}
