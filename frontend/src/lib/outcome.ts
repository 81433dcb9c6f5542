import { formatMass, formatRate } from './units';

/** The server's target-vs-applied figures of a job (`agronomy.prescription.application_outcome`). */
export interface Outcome {
  target_kg?: number | null;
  applied_kg?: number | null;
  target_kg_ha?: number | null;
  applied_kg_ha?: number | null;
  difference_pct?: number | null;
  under_area_pct?: number | null;
  over_area_pct?: number | null;
  tolerance_pct?: number | null;
}

/** Said once where areas are shown: every area is on the same basis (`geo.crs.AREA_BASIS`). */
export const AREA_BASIS_NOTE = "Areas are measured flat in the field's UTM zone (where its plan is built).";

function signed(pct: number): string {
  return `${pct >= 0 ? '+' : '−'}${Math.abs(pct).toFixed(1)} %`;
}

/**
 * The report's headline rows: target vs applied (kg and kg/ha, with the difference) and the
 * share of the area applied more than the tolerance below / above its target. Empty when the
 * report has no outcome yet.
 */
export function outcomeRows(o: Outcome | null | undefined): [string, string, string][] {
  if (!o || o.target_kg == null || o.applied_kg == null) return [];
  const diff = o.difference_pct != null ? `, ${signed(o.difference_pct)}` : '';
  const tol = o.tolerance_pct ?? 10;
  const share = (x: number | null | undefined) => (x != null ? `${x.toFixed(1)} %` : '–');
  return [
    [
      'Target → applied',
      `${formatMass(o.target_kg)} (${formatRate(o.target_kg_ha)}) → ${formatMass(o.applied_kg)} (${formatRate(o.applied_kg_ha)})${diff}`,
      'report-outcome',
    ],
    [`Area under / over by > ${tol} %`, `${share(o.under_area_pct)} / ${share(o.over_area_pct)}`, 'report-outcome-share'],
  ];
}

/** "2026-11-28 07:02 UTC" of an ISO time or epoch seconds; '–' when unknown. */
export function utcMinute(t: string | number | null | undefined): string {
  if (t == null) return '–';
  const d = typeof t === 'number' ? new Date(t * 1000) : new Date(t);
  return Number.isNaN(d.getTime()) ? '–' : d.toISOString().replace('T', ' ').slice(0, 16) + ' UTC';
}
