import type { Schemas } from '../api/client';
import { alsoInUnit, formatProduct, nutrientRateText, outsideMeter, summaryFractions, type ShownUnit } from '../lib/rxform';
import { formatRate } from '../lib/units';
import { Kv } from './Status';

type Summary = Schemas['RxSummary'];
interface CurveShare {
  count: number;
  share: number;
  flagged: boolean;
}
interface Plausibility {
  ceilings?: Record<string, { kg_ha: number; source: string }>;
  above_ceiling?: {
    count: number;
    area_m2: number;
    seq: number[];
    nutrients?: Record<string, { ceiling_kg_ha: number; max_kg_ha: number; count: number; source: string }>;
  } | null;
  curve_limits?: { cap: CurveShare; floor: CurveShare; cap_kg_ha: number; floor_kg_ha: number; share_max: number };
}

/** The ceilings the version was checked against, with their sources. */
function CeilingLines({ plaus }: { plaus: Plausibility }) {
  const c = Object.entries(plaus.ceilings ?? {});
  if (!c.length) return null;
  return (
    <p className="small muted" data-testid="rx-ceilings">
      Ceilings: {c.map(([n, x]) => `${x.kg_ha} kg ${n}/ha (${x.source})`).join('; ')}
    </p>
  );
}

/**
 * The whole-field figures of the version on screen (server summary, every cell): area,
 * product (kg or t), mean / min / max rate, nutrients per ha, cost, the clamp and what it
 * changed, the meter range the rates were checked against beside the rate range, and where
 * each model parameter came from.
 */
export function RxSummaryPanel({
  summary: s,
  version,
  unit = null,
}: {
  summary: Summary | null | undefined;
  version: number | null;
  /** the prescription's unit, when its rates are also shown in it (seeds/ha, ...) */
  unit?: ShownUnit | null;
}) {
  if (!s) return <p className="muted">Loading the version's figures…</p>;
  const nut = s.nutrients_kg_ha ?? null;
  const meter = s.meter as { rate_min_kg_ha?: number; rate_max_kg_ha?: number; speed_min_kmh?: number; speed_max_kmh?: number } | null;
  const warn = meter?.rate_min_kg_ha != null && meter.rate_max_kg_ha != null ? outsideMeter(s, meter.rate_min_kg_ha, meter.rate_max_kg_ha) : null;
  const fl = (s.flagged ?? {}) as Record<string, number>;
  const fla = (s.flagged_area_m2 ?? {}) as Record<string, number>;
  const raised = fl.clamped_min ?? 0;
  const lowered = fl.clamped_max ?? 0;
  const clamp = s.clamp;
  const product = s.product as { name?: string; price_per_t?: number | null } | null;
  const fr = summaryFractions(s);
  const seedLot = product != null && !['n_pct', 'p2o5_pct', 'k2o_pct'].some((k) => k in product);
  const plaus = (s.plausibility ?? {}) as Plausibility;
  const above = plaus.above_ceiling;
  const origin = (s.param_origin ?? {}) as Record<string, string>;
  return (
    <div className="rx-summary" data-testid="rx-summary" data-version={version ?? ''}>
      <Kv
        items={[
          ['Area', `${(s.area_ha ?? 0).toFixed(3)} ha`, 'rx-sum-area'],
          ['Product', product?.name ?? '–', 'rx-sum-product-name'],
          ['Total product', formatProduct(s.product_kg), 'rx-sum-product'],
          ['Mean rate', nutrientRateText(s.rate_mean_kg_ha, fr) + alsoInUnit(s.rate_mean_kg_ha, unit), 'rx-sum-mean'],
          [
            'Rate range',
            <>
              {formatRate(s.rate_min_kg_ha)} – {formatRate(s.rate_max_kg_ha)}
              {unit && (
                <span data-testid="rx-range-unit">
                  {' '}
                  ({alsoInUnit(s.rate_min_kg_ha, unit).slice(3)} – {alsoInUnit(s.rate_max_kg_ha, unit).slice(3)})
                </span>
              )}
              {fr.N ? (
                <span data-testid="rx-range-n">
                  {' '}
                  ({((s.rate_min_kg_ha ?? 0) * fr.N).toFixed(1)} – {((s.rate_max_kg_ha ?? 0) * fr.N).toFixed(1)} kg N/ha)
                </span>
              ) : null}
              {meter?.rate_min_kg_ha != null && (
                <span className="small muted" data-testid="rx-meter-range">
                  {' '}
                  · machine meters {formatRate(meter.rate_min_kg_ha)} – {formatRate(meter.rate_max_kg_ha)} at {meter.speed_min_kmh}–
                  {meter.speed_max_kmh} km/h
                </span>
              )}
            </>,
            'rx-range',
          ],
          // a seed lot (a product that states no nutrient) carries none to show
          ...(seedLot
            ? []
            : [
                [
                  'Nutrients',
                  nut
                    ? Object.entries(nut)
                        .filter(([, v]) => v > 0)
                        .map(([k, v]) => `${v.toFixed(1)} kg ${k}/ha`)
                        .join(', ') || '0'
                    : 'choose a product to see kg N/ha',
                  'rx-sum-n',
                ] as [string, string, string],
              ]),
          [
            'Cost',
            s.cost != null ? s.cost.toLocaleString('en-US', { maximumFractionDigits: 2 }) : product ? 'no price set for the product' : '–',
            'rx-sum-cost',
          ],
        ]}
      />
      <CeilingLines plaus={plaus} />
      {above && above.count > 0 && (
        <p className="warn small" data-testid="rx-ceiling-warn">
          {above.count} cell{above.count === 1 ? '' : 's'} ({(above.area_m2 / 10_000).toFixed(3)} ha) above a nutrient ceiling:{' '}
          {Object.entries(above.nutrients ?? {})
            .filter(([, x]) => x.count > 0)
            .map(([n, x]) => `${x.count} over ${x.ceiling_kg_ha} kg ${n}/ha (up to ${x.max_kg_ha.toFixed(1)}; ${x.source})`)
            .join('; ')}
          . Cells: {above.seq.slice(0, 20).join(', ')}
          {above.seq.length > 20 ? ' …' : ''}. Sending needs your confirmation.
        </p>
      )}
      {(['cap', 'floor'] as const).map((k) =>
        plaus.curve_limits?.[k]?.flagged ? (
          <p key={k} className="warn small" data-testid={`rx-curve-${k}-warn`}>
            {(plaus.curve_limits[k].share * 100).toFixed(0)} % of the field ({plaus.curve_limits[k].count} cells) is at the rate curve's {k} (
            {formatRate(k === 'cap' ? plaus.curve_limits.cap_kg_ha : plaus.curve_limits.floor_kg_ha)}), more than{' '}
            {(plaus.curve_limits.share_max * 100).toFixed(0)} %: check the input's scale. Sending needs your confirmation.
          </p>
        ) : null,
      )}
      {warn && (
        <p className="warn small" data-testid="rx-meter-warn">
          Outside what the machine meters: {warn}.
        </p>
      )}
      {(clamp || raised + lowered > 0) && (
        <p className={raised + lowered > 0 ? 'warn small' : 'small muted'} data-testid="rx-clamp">
          Clamp {clamp?.min_kg_ha != null ? formatRate(clamp.min_kg_ha) : 'none'} – {clamp?.max_kg_ha != null ? formatRate(clamp.max_kg_ha) : 'none'}:{' '}
          {raised} cell{raised === 1 ? '' : 's'} raised, {lowered} lowered (
          {(((fla.clamped_min ?? 0) + (fla.clamped_max ?? 0)) / 10_000).toFixed(3)} ha)
          {clamp?.model_min_kg_ha != null && ` · model gave ${formatRate(clamp.model_min_kg_ha)} – ${formatRate(clamp.model_max_kg_ha)}`}
        </p>
      )}
      {s.param_sources && Object.keys(s.param_sources).length > 0 && (
        <details className="small">
          <summary>Parameters and their sources</summary>
          <ul data-testid="rx-param-sources">
            {Object.entries(s.param_sources).map(([k, src]) => (
              <li key={k}>
                {k} = {String((s.params as Record<string, unknown> | undefined)?.[k] ?? '')}
                {origin[k] ? <strong data-testid={`rx-origin-${k}`}> ({origin[k]})</strong> : null} — {src}
              </li>
            ))}
          </ul>
        </details>
      )}
    </div>
  );
}
