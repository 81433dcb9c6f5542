/**
 * Seed 000's sensor-based topdressing: the rate-curve preview under its form, and its report's
 * figures (shaft-speed error, Table 3) and map views (filtered NDVI, applied rate).
 */
import { formatRate } from '../lib/units';
import { f1, type KindUi } from './types';

/** Seed 000's NDVI -> rate line through two points, clamped between them (the preview). */
export function ndviRate(ndvi: number, lo: number, rateLo: number, hi: number, rateHi: number): number {
  if (!(hi > lo)) return NaN;
  const t = Math.min(1, Math.max(0, (ndvi - lo) / (hi - lo)));
  return rateLo + t * (rateHi - rateLo);
}

/** Preview rows at NDVI 0.2 .. 0.7 in steps of 0.1 for the form's curve values. */
export function ndviPreview(values: Record<string, string>): { ndvi: number; rate: number }[] {
  const g = (p: string, d: number) => (values[p] != null && values[p] !== '' ? Number(values[p]) : d);
  const lo = g('rate_curve.ndvi_lo', 0.24);
  const hi = g('rate_curve.ndvi_hi', 0.65);
  const rl = g('rate_curve.rate_at_lo_kg_ha', 375);
  const rh = g('rate_curve.rate_at_hi_kg_ha', 180);
  return [0.2, 0.3, 0.4, 0.5, 0.6, 0.7].map((n) => ({ ndvi: n, rate: ndviRate(n, lo, rl, hi, rh) }));
}

export interface ShaftBand {
  speed_kmh: number;
  n: number;
  theoretical_rpm?: number;
  monitored_rpm?: number;
  relative_error_pct?: number;
}

function ShaftTable({ bands }: { bands: ShaftBand[] }) {
  const paper = [2.0, 3.6, 3.8, 4.0];
  return (
    <table className="table small" data-testid="shaft-table">
      <thead>
        <tr>
          <th>Speed km/h</th>
          <th>Theoretical r/min</th>
          <th>Monitored r/min</th>
          <th>Rel. error %</th>
          <th>Paper %</th>
        </tr>
      </thead>
      <tbody>
        {bands.map((b, i) => (
          <tr key={b.speed_kmh}>
            <td>{b.speed_kmh}</td>
            <td>{f1(b.theoretical_rpm)}</td>
            <td>{f1(b.monitored_rpm)}</td>
            <td>{f1(b.relative_error_pct, 2)}</td>
            <td className="muted">{paper[i] ?? '–'}</td>
          </tr>
        ))}
      </tbody>
    </table>
  );
}

export const ui: KindUi = {
  name: 'ndvi_topdress',
  formNote: (values) => (
    <p className="muted small" data-testid="ndvi-preview">
      Rate preview:{' '}
      {ndviPreview(values)
        .map((p) => `NDVI ${p.ndvi.toFixed(1)} → ${formatRate(p.rate, 0)}`)
        .join(' · ')}
      . Width and metering calibration are the machine&apos;s;{' '}
      {values.restrict_to_boundary === 'false' ? 'meters wherever it drives.' : 'no fertilizer outside the field boundary.'}
    </p>
  ),
  views: [
    { key: 'ndvi', label: 'NDVI (filtered)', column: 'ndvi', decimals: 2 },
    { key: 'rate', label: 'Applied rate (kg/ha)', column: 'applied_rate_kg_ha', decimals: 0 },
  ],
  reportRows: (r) => [['Mean shaft-speed error', `${f1(r.mean_relative_error_pct, 2)} % (paper 3.35 %)`, 'report-shaft-error']],
  reportTable: (r) => <ShaftTable bands={((r.shaft_table as Record<string, unknown> | undefined)?.bands ?? []) as ShaftBand[]} />,
};
