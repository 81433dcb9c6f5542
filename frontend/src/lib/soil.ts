import type { Schemas } from '../api/client';
import { classColors, niceBreaks, stepExpression } from './colors';

type SoilFC = Schemas['SampleCollection'];
export type SampleKey = keyof Schemas['SampleProps'];

/** Sample properties that are bookkeeping, not measurements (not tabulated, not coloured by). */
export const SKIP_KEYS = new Set<string>([
  'id',
  'field_id',
  'geometry',
  'lon',
  'lat',
  'created_at',
  'organisation_id',
  'import_batch',
  'import_id',
]);

/**
 * The soil samples' columns and the colouring of the map by one of them: `key` is the chosen
 * numeric property if it has numbers, else the nitrogen one, else the first numeric; five
 * classes over its range (`niceBreaks`).
 */
export function soilColoring(soil: SoilFC | null | undefined, chosen: string) {
  const first = soil?.features[0];
  const sampleKeys = first ? (Object.keys(first.properties) as SampleKey[]).filter((k) => !SKIP_KEYS.has(k)) : [];
  const numericKeys = sampleKeys.filter((k) => soil!.features.some((f) => typeof f.properties[k] === 'number'));
  const key: SampleKey | '' =
    chosen && numericKeys.includes(chosen as SampleKey)
      ? (chosen as SampleKey)
      : (numericKeys.find((k) => /^n_|nitrogen/i.test(k)) ?? numericKeys[0] ?? '');
  const vals = key ? (soil?.features ?? []).map((f) => Number(f.properties[key])).filter(Number.isFinite) : [];
  const lo = vals.length ? vals.reduce((a, b) => Math.min(a, b)) : 0;
  const hi = vals.length ? vals.reduce((a, b) => Math.max(a, b)) : 1;
  const breaks = niceBreaks(lo, hi === lo ? lo + 1 : hi, 5);
  const colors = classColors(breaks.length - 1);
  const expr: unknown = key ? stepExpression(key, breaks, colors) : '#8b4513';
  return { sampleKeys, numericKeys, key, breaks, colors, expr };
}

/** A sample's popup: its measurements as a table (values escaped). */
export function samplePopup(props: Record<string, unknown>): string {
  const esc = (s: string) => s.replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
  const rows = Object.entries(props)
    .filter(([k]) => !SKIP_KEYS.has(k))
    .map(([k, v]) => `<tr><th>${esc(k)}</th><td>${esc(String(v))}</td></tr>`)
    .join('');
  return `<table class="popup">${rows}</table>`;
}

export function fmtCell(v: unknown): string {
  if (typeof v === 'number') return Number.isInteger(v) ? String(v) : v.toFixed(2);
  return v == null ? '' : String(v);
}
