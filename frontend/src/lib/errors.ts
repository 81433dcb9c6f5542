/** Turning API error bodies into something a screen can show (and place on the map). */
import { plainName } from './words';

/** Where in the request FastAPI says a field is: not part of the field's name. */
const LOC_ROOTS = new Set(['body', 'query', 'path']);

export interface ErrorItem {
  message: string;
  loc?: (string | number)[];
  row?: number;
}

export interface ParsedError {
  message: string;
  items: ErrorItem[];
  /** [lon, lat] where the server says the problem is (e.g. a self-intersection). */
  location?: [number, number];
}

function asLocation(v: unknown): [number, number] | undefined {
  if (Array.isArray(v) && v.length >= 2 && typeof v[0] === 'number' && typeof v[1] === 'number')
    return [v[0], v[1]];
  if (v && typeof v === 'object') {
    const o = v as Record<string, unknown>;
    if (o.type === 'Point') return asLocation(o.coordinates);
    if (typeof o.lon === 'number' && typeof o.lat === 'number') return [o.lon, o.lat];
  }
  return undefined;
}

/**
 * Accepts {"detail": "msg", "location": [lon, lat]?} and FastAPI's
 * {"detail": [{"loc": [...], "msg": "..."}]}; row numbers (CSV uploads) are
 * picked up from a "row" key or a numeric loc element after "row"/"rows".
 */
export function parseApiError(body: unknown, status = 0): ParsedError {
  if (body == null || typeof body !== 'object') {
    return { message: typeof body === 'string' && body ? body : `HTTP ${status}`, items: [] };
  }
  const b = body as Record<string, unknown>;
  const d = b.detail;
  let location = asLocation(b.location);
  if (typeof d === 'string') {
    const items: ErrorItem[] = [];
    if (Array.isArray(b.errors)) items.push(...(b.errors as unknown[]).map(toItem));
    return { message: d, items, location };
  }
  if (Array.isArray(d)) {
    const items = d.map(toItem);
    if (!location) {
      for (const x of d) {
        const l = x && typeof x === 'object' ? asLocation((x as Record<string, unknown>).location) : undefined;
        if (l) {
          location = l;
          break;
        }
      }
    }
    const message = items.length === 1 ? items[0].message : `${items.length} problems`;
    return { message, items, location };
  }
  if (d && typeof d === 'object') {
    const o = d as Record<string, unknown>;
    const items = Array.isArray(o.errors) ? (o.errors as unknown[]).map(toItem) : [];
    return {
      message: String(o.message ?? o.msg ?? `HTTP ${status}`),
      items,
      location: location ?? asLocation(o.location),
    };
  }
  return { message: `HTTP ${status}`, items: [] };
}

function toItem(x: unknown): ErrorItem {
  if (typeof x === 'string') return { message: x };
  if (!x || typeof x !== 'object') return { message: String(x) };
  const o = x as Record<string, unknown>;
  const loc = Array.isArray(o.loc) ? (o.loc as (string | number)[]) : undefined;
  let row = typeof o.row === 'number' ? o.row : undefined;
  if (row == null && loc) {
    const i = loc.findIndex((p) => p === 'row' || p === 'rows');
    if (i >= 0 && typeof loc[i + 1] === 'number') row = loc[i + 1] as number;
  }
  const msg = String(o.msg ?? o.message ?? o.reason ?? JSON.stringify(o));
  // the field in words ("swath width (m)"), not the request's key ("swath_width_m")
  const where = loc ? plainName(loc.filter((p) => !LOC_ROOTS.has(String(p))).join('.')) : '';
  return { message: row != null ? `row ${row}: ${msg}` : where ? `${where}: ${msg}` : msg, loc, row };
}
