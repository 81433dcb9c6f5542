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
