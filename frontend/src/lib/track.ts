/** Normalising track / telemetry responses (array, {items}, or GeoJSON points) into records. */

export interface TrackPoint {
  t: number; // unix seconds
  lon: number | null;
  lat: number | null;
  speed_raw_m_s: number | null;
  speed_filtered_m_s: number | null;
  heading_deg: number | null;
  target_shaft_rpm: number | null;
  actual_shaft_rpm: number | null;
  target_rate_kg_ha: number | null;
  applied_rate_kg_ha: number | null;
  cell_seq: number | null;
  job_id: number | null;
}

function n(v: unknown): number | null {
  if (v == null || v === '') return null;
  const x = Number(v);
  return Number.isFinite(x) ? x : null;
}

/** ISO strings and epoch milliseconds both become unix seconds. */
export function toUnixSeconds(v: unknown): number | null {
  if (typeof v === 'number') return v > 1e12 ? v / 1000 : v;
  if (typeof v === 'string') {
    const num = Number(v);
    if (Number.isFinite(num)) return toUnixSeconds(num);
    const ms = Date.parse(v);
    return Number.isFinite(ms) ? ms / 1000 : null;
  }
  return null;
}

export function normaliseTrack(r: unknown): TrackPoint[] {
  let rows: Record<string, unknown>[] = [];
  if (Array.isArray(r)) rows = r as Record<string, unknown>[];
  else if (r && typeof r === 'object') {
    const o = r as Record<string, unknown>;
    if (o.type === 'FeatureCollection' && Array.isArray(o.features)) {
      rows = (o.features as { geometry?: { coordinates?: number[] }; properties?: Record<string, unknown> }[]).map(
        (f) => ({ ...(f.properties ?? {}), lon: f.geometry?.coordinates?.[0], lat: f.geometry?.coordinates?.[1] }),
      );
    } else {
      for (const k of ['items', 'records', 'points', 'track', 'data'])
        if (Array.isArray(o[k])) {
          rows = o[k] as Record<string, unknown>[];
          break;
        }
    }
  }
  const out: TrackPoint[] = [];
  for (const x of rows) {
    const t = toUnixSeconds(x.t ?? x.time ?? x.ts ?? x.timestamp);
    if (t == null) continue;
    out.push({
      t,
      lon: n(x.lon),
      lat: n(x.lat),
      speed_raw_m_s: n(x.speed_raw_m_s),
      speed_filtered_m_s: n(x.speed_filtered_m_s),
      heading_deg: n(x.heading_deg),
      target_shaft_rpm: n(x.target_shaft_rpm),
      actual_shaft_rpm: n(x.actual_shaft_rpm),
      target_rate_kg_ha: n(x.target_rate_kg_ha),
      applied_rate_kg_ha: n(x.applied_rate_kg_ha),
      cell_seq: n(x.cell_seq),
      job_id: n(x.job_id),
    });
  }
  out.sort((a, b) => a.t - b.t);
  return out;
}

/** Index of the last point at or before time t (binary search), for the replay slider. */
export function indexAtTime(points: { t: number }[], t: number): number {
  let lo = 0;
  let hi = points.length - 1;
  if (hi < 0 || t < points[0].t) return -1;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (points[mid].t <= t) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

/** Thin a series to at most maxPoints by striding (charts stay responsive on long tracks). */
export function decimate<T>(xs: T[], maxPoints: number): T[] {
  if (xs.length <= maxPoints || maxPoints < 2) return xs;
  const step = (xs.length - 1) / (maxPoints - 1);
  return Array.from({ length: maxPoints }, (_, i) => xs[Math.round(i * step)]);
}
