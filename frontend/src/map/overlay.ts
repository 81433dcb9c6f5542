/**
 * The one place that adds, updates and removes map sources and layers (the
 * traccar-web pattern): an overlay component describes its source and layers as an
 * `OverlaySpec`, and `syncOverlay` turns the difference between the previous and the next
 * spec into the fewest map calls (setData for new GeoJSON, setPaintProperty for a new colour
 * scale, re-create only when the source itself changed). Pure over a `MapLike`, so the rules
 * are unit-tested without WebGL.
 *
 * Stacking: overlays mount in any order, so each names a `Slot`; MapView adds one hidden
 * anchor layer per slot on load and an overlay's layers go just below its slot's anchor.
 * Imagery is always under grids, grids under areas, boundaries, tracks and points, whatever
 * order the screen composes them in. `top` layers go above everything, terra-draw included,
 * and move back to the top on every update.
 */
import type * as maplibregl from 'maplibre-gl';

export type Slot = 'imagery' | 'grid' | 'area' | 'line' | 'track' | 'point' | 'top';

/** Bottom to top. */
export const SLOTS: readonly Slot[] = ['imagery', 'grid', 'area', 'line', 'track', 'point', 'top'];

export function slotAnchorId(slot: Slot): string {
  return `slot:${slot}`;
}

/** A layer of an overlay: a MapLibre layer without `source` (the overlay's own source is used). */
export type OverlayLayer = DistributiveOmit<SourcedLayer, 'source'>;
type SourcedLayer = Exclude<maplibregl.LayerSpecification, maplibregl.BackgroundLayerSpecification>;
type DistributiveOmit<T, K extends PropertyKey> = T extends unknown ? Omit<T, K> : never;

export interface OverlaySpec {
  /** Source id (unique on the map). */
  id: string;
  source: maplibregl.SourceSpecification;
  layers: OverlayLayer[];
  slot: Slot;
}

/** The subset of `maplibregl.Map` the sync needs (a test double implements just this). */
export type MapLike = Pick<
  maplibregl.Map,
  | 'addSource'
  | 'removeSource'
  | 'getSource'
  | 'addLayer'
  | 'removeLayer'
  | 'getLayer'
  | 'moveLayer'
  | 'setPaintProperty'
  | 'setLayoutProperty'
  | 'setFilter'
  | 'setLayerZoomRange'
>;

/** Hidden layers marking the top of each slot; MapView adds them once the style is loaded. */
export function addSlotAnchors(map: MapLike): void {
  for (const s of SLOTS) {
    if (s === 'top' || map.getLayer(slotAnchorId(s))) continue;
    map.addLayer({ id: slotAnchorId(s), type: 'background', layout: { visibility: 'none' } });
  }
}

export type SyncResult = 'none' | 'added' | 'updated' | 'removed';

/**
 * Bring the map from `prev` to `next` (either may be null: mount / unmount).
 * Returns 'added' when the source was (re)created, so callers can time the first frame.
 */
export function syncOverlay(map: MapLike, prev: OverlaySpec | null, next: OverlaySpec | null): SyncResult {
  if (!next) {
    if (prev) removeOverlay(map, prev);
    return prev ? 'removed' : 'none';
  }
  if (!prev || prev.id !== next.id || sourceKey(prev.source) !== sourceKey(next.source)) {
    if (prev) removeOverlay(map, prev);
    addOverlay(map, next);
    return 'added';
  }
  let changed = false;
  if (next.source.type === 'geojson' && prev.source.type === 'geojson' && prev.source.data !== next.source.data) {
    (map.getSource(next.id) as maplibregl.GeoJSONSource | undefined)?.setData(next.source.data as GeoJSON.GeoJSON);
    changed = true;
  }
  const sameShape =
    prev.slot === next.slot &&
    prev.layers.length === next.layers.length &&
    prev.layers.every((l, i) => l.id === next.layers[i].id && l.type === next.layers[i].type);
  if (!sameShape) {
    for (const l of prev.layers) if (map.getLayer(l.id)) map.removeLayer(l.id);
    addLayers(map, next);
    return 'updated';
  }
  next.layers.forEach((l, i) => {
    if (updateLayer(map, prev.layers[i], l)) changed = true;
  });
  if (next.slot === 'top') for (const l of next.layers) if (map.getLayer(l.id)) map.moveLayer(l.id);
  return changed ? 'updated' : 'none';
}

function addOverlay(map: MapLike, spec: OverlaySpec): void {
  // Left-overs of the same id (a screen that still adds layers by hand) would make addSource throw.
  for (const l of spec.layers) if (map.getLayer(l.id)) map.removeLayer(l.id);
  if (map.getSource(spec.id)) map.removeSource(spec.id);
  map.addSource(spec.id, spec.source);
  addLayers(map, spec);
}

function addLayers(map: MapLike, spec: OverlaySpec): void {
  const anchor = spec.slot === 'top' ? undefined : slotAnchorId(spec.slot);
  const before = anchor && map.getLayer(anchor) ? anchor : undefined;
  for (const l of spec.layers) map.addLayer({ ...l, source: spec.id } as maplibregl.LayerSpecification, before);
}

function removeOverlay(map: MapLike, spec: OverlaySpec): void {
  for (const l of spec.layers) if (map.getLayer(l.id)) map.removeLayer(l.id);
  if (map.getSource(spec.id)) map.removeSource(spec.id);
}

/** A source's identity without its GeoJSON data (new data is a setData, not a new source). */
function sourceKey(s: maplibregl.SourceSpecification): string {
  if (s.type === 'geojson') {
    const { data: _data, ...rest } = s;
    return JSON.stringify(rest);
  }
  return JSON.stringify(s);
}

type Props = Record<string, unknown>;

function updateLayer(map: MapLike, prev: OverlayLayer, next: OverlayLayer): boolean {
  let changed = false;
  const pp = ((prev as { paint?: Props }).paint ?? {}) as Props;
  const np = ((next as { paint?: Props }).paint ?? {}) as Props;
  for (const k of new Set([...Object.keys(pp), ...Object.keys(np)])) {
    if (JSON.stringify(pp[k]) !== JSON.stringify(np[k])) {
      map.setPaintProperty(next.id, k as never, np[k] as never);
      changed = true;
    }
  }
  const pl = ((prev as { layout?: Props }).layout ?? {}) as Props;
  const nl = ((next as { layout?: Props }).layout ?? {}) as Props;
  for (const k of new Set([...Object.keys(pl), ...Object.keys(nl)])) {
    if (JSON.stringify(pl[k]) !== JSON.stringify(nl[k])) {
      map.setLayoutProperty(next.id, k as never, nl[k] as never);
      changed = true;
    }
  }
  const pf = (prev as { filter?: unknown }).filter;
  const nf = (next as { filter?: unknown }).filter;
  if (JSON.stringify(pf) !== JSON.stringify(nf)) {
    map.setFilter(next.id, (nf ?? null) as maplibregl.FilterSpecification | null);
    changed = true;
  }
  if (prev.minzoom !== next.minzoom || prev.maxzoom !== next.maxzoom) {
    map.setLayerZoomRange(next.id, next.minzoom ?? 0, next.maxzoom ?? 24);
    changed = true;
  }
  return changed;
}
