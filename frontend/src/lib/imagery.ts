/** Imagery under the maps: which image to show first, where its layer goes, map start view. */
import type { Schemas } from '../api/client';
import type { BBox } from './geo';

export type ImageryKind = Schemas['ImageryOut']['kind'];

/** The keys of the server's `ImageryOut` these helpers read. */
export type ImageryItem = Pick<
  Schemas['ImageryOut'],
  'id' | 'field_id' | 'kind' | 'name' | 'acquired_on' | 'created_at' | 'resolution_m' | 'bounds' | 'tiles'
>;

/** Newest first: acquisition date (unknown dates last), then upload time, then id. */
export function sortNewest(items: ImageryItem[]): ImageryItem[] {
  return [...items].sort((a, b) => {
    const da = a.acquired_on ?? '';
    const db = b.acquired_on ?? '';
    if (da !== db) return da === '' ? 1 : db === '' ? -1 : db.localeCompare(da);
    const ca = a.created_at ?? '';
    const cb = b.created_at ?? '';
    if (ca !== cb) return cb.localeCompare(ca);
    return b.id - a.id;
  });
}

/** What a map shows by default: the field's newest orthophoto, else its newest image, else none. */
export function defaultImagery(items: ImageryItem[], fieldId?: number): ImageryItem | null {
  const mine = fieldId === undefined ? items : items.filter((i) => i.field_id === fieldId);
  const sorted = sortNewest(mine);
  return sorted.find((i) => i.kind === 'orthophoto') ?? sorted[0] ?? null;
}

/** Opacity from a 0..100 slider value, clamped (NaN -> fully opaque). */
export function opacityFromPercent(pct: number): number {
  if (!Number.isFinite(pct)) return 1;
  return Math.min(1, Math.max(0, pct / 100));
}

export function imageryLabel(i: ImageryItem): string {
  const date = i.acquired_on ?? 'undated';
  const res = i.resolution_m < 1 ? `${Math.round(i.resolution_m * 100)} cm` : `${i.resolution_m.toFixed(1)} m`;
  return `${i.kind} ${date} (${res}) ${i.name}`.trim();
}

/**
 * Where a map opens before a screen fits its own content: the organisation's fields when
 * known; otherwise null (the caller keeps its default view until the extent arrives).
 */
export function startBounds(fieldsBbox: BBox | null): BBox | null {
  if (!fieldsBbox) return null;
  const ok = fieldsBbox.every((v) => Number.isFinite(v)) && fieldsBbox[0] <= fieldsBbox[2] && fieldsBbox[1] <= fieldsBbox[3];
  return ok ? fieldsBbox : null;
}

/**
 * The server's NDVI colouring (backend imagery/tiles.py: rio-tiler's "rdylgn" colormap
 * over NDVI 0..1, clamped), sampled at 11 even steps from that colormap: what the
 * legend shows is what the tiles draw.
 */
export const NDVI_RANGE: readonly [number, number] = [0, 1];
export const NDVI_RAMP = [
  '#a50026', '#d62f26', '#f46d43', '#fcac60', '#fee08b', '#fefebd',
  '#d9ef8b', '#a7d96a', '#66bd63', '#1b9850', '#006837',
] as const;

export interface NdviLegend {
  /** CSS linear-gradient of the ramp, low NDVI on the left. */
  gradient: string;
  /** Value labels under the bar, at their position in percent. */
  ticks: { value: string; pct: number }[];
}

/** Legend of an image drawn as NDVI (an NDVI raster, or NDVI from a multispectral one); null for a photo. */
export function ndviLegend(kind: ImageryKind | undefined | null): NdviLegend | null {
  if (kind !== 'ndvi' && kind !== 'multispectral') return null;
  const [lo, hi] = NDVI_RANGE;
  const stops = NDVI_RAMP.map((c, i) => `${c} ${((100 * i) / (NDVI_RAMP.length - 1)).toFixed(0)}%`);
  const ticks = [0, 0.25, 0.5, 0.75, 1].map((t) => ({ value: (lo + t * (hi - lo)).toFixed(2), pct: 100 * t }));
  return { gradient: `linear-gradient(to right, ${stops.join(', ')})`, ticks };
}
