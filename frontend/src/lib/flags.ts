/**
 * Cells a prescription will not deliver as asked: outside the machine's meter
 * range at the planned speeds (stored as asked, flagged) or without a nearby
 * soil sample (fallback rate). Shown wherever a prescription is shown, and a
 * job with such cells is sent only after an explicit confirmation.
 */

export interface Attention {
  count: number;
  areaM2: number;
  seq: number[];
  noData: number;
  outOfRange: number;
  below: number;
  above: number;
  aboveCeiling: number;
  atCurveLimit: number;
  fallbackRate?: number | null;
  meter?: { rate_min_kg_ha: number; rate_max_kg_ha: number; speed_min_kmh: number; speed_max_kmh: number } | null;
  searchDistanceM?: number | null;
}

type Obj = Record<string, unknown>;

function o(v: unknown): Obj {
  return v && typeof v === 'object' ? (v as Obj) : {};
}

function n(v: unknown): number {
  return typeof v === 'number' && Number.isFinite(v) ? v : 0;
}

/** Reads the server's prescription summary (GET /prescriptions/{id}). */
export function attentionOf(rx: unknown): Attention {
  const r = o(rx);
  const s = o(r.summary);
  const att = o(s.attention);
  const fl = o(s.flagged);
  const interp = o(s.interpolation);
  const meter = o(s.meter);
  return {
    count: n(att.count),
    areaM2: n(att.area_m2),
    seq: Array.isArray(att.seq) ? (att.seq as number[]) : [],
    noData: n(fl.no_data),
    below: n(fl.below_meter_range),
    above: n(fl.above_meter_range),
    outOfRange: n(fl.below_meter_range) + n(fl.above_meter_range),
    aboveCeiling: n(fl.above_nutrient_ceiling),
    atCurveLimit: n(fl.at_curve_limit),
    fallbackRate: (r.fallback_rate_kg_ha ?? s.fallback_rate_kg_ha) as number | null | undefined,
    meter: 'rate_min_kg_ha' in meter ? (meter as unknown as Attention['meter']) : null,
    searchDistanceM: typeof interp.search_distance_m === 'number' ? interp.search_distance_m : null,
  };
}

/** "12 cells (0.034 ha)": count and area of the flagged cells. */
export function attentionSummary(a: Pick<Attention, 'count' | 'areaM2'>): string {
  return `${a.count} cell${a.count === 1 ? '' : 's'} (${(a.areaM2 / 10_000).toFixed(3)} ha)`;
}

/** One line per reason, naming the limit and the speeds, or the fallback rate. */
export function attentionLines(a: Attention): string[] {
  const out: string[] = [];
  const m = a.meter;
  if (a.below)
    out.push(
      `${a.below} below the lowest meterable rate${m ? ` ${m.rate_min_kg_ha.toFixed(1)} kg/ha at ${m.speed_min_kmh} km/h` : ''}`,
    );
  if (a.above)
    out.push(
      `${a.above} above the highest meterable rate${m ? ` ${m.rate_max_kg_ha.toFixed(1)} kg/ha at ${m.speed_max_kmh} km/h` : ''}`,
    );
  if (a.aboveCeiling) out.push(`${a.aboveCeiling} above a nutrient ceiling (kg N, P2O5 or K2O per ha)`);
  if (a.atCurveLimit) out.push(`${a.atCurveLimit} at the rate curve's cap or floor (more of the field than allowed)`);
  if (a.noData)
    out.push(
      `${a.noData} with no soil sample${a.searchDistanceM ? ` within ${Math.round(a.searchDistanceM)} m` : ''}: fallback rate ${
        a.fallbackRate != null ? `${a.fallbackRate.toFixed(1)} kg/ha` : '(model mean)'
      }`,
    );
  return out;
}

/** The 409 body of POST /jobs when the sender must confirm flagged cells; null for other errors. */
export function flaggedConfirmation(status: number, body: unknown): { message: string; count: number; areaM2: number; seq: number[] } | null {
  const b = o(body);
  if (status !== 409 || b.where !== 'confirm_flagged') return null;
  const f = o(b.flagged);
  return {
    message: String(b.detail ?? ''),
    count: n(f.count),
    areaM2: n(f.area_m2),
    seq: Array.isArray(f.seq) ? (f.seq as number[]) : [],
  };
}
