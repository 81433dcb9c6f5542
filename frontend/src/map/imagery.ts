/** The imagery raster layer on a MapLibre map: one per map, under every data layer. */
import type * as maplibregl from 'maplibre-gl';
import type { BBox } from '../lib/geo';
import { imageryBeforeId, type ImageryItem } from '../lib/imagery';
import { absoluteApiUrl } from './setup';

export const IMAGERY_ID = 'imagery';

/** Show ``item`` (or nothing) at ``opacity``; replaces the previous image. */
export function showImagery(map: maplibregl.Map, item: ImageryItem | null, opacity: number): void {
  const current = map.getSource(IMAGERY_ID) as (maplibregl.RasterTileSource & { _fieldrxId?: number }) | undefined;
  if (current && (!item || current._fieldrxId !== item.id)) {
    if (map.getLayer(IMAGERY_ID)) map.removeLayer(IMAGERY_ID);
    map.removeSource(IMAGERY_ID);
  }
  if (!item) return;
  if (!map.getSource(IMAGERY_ID)) {
    map.addSource(IMAGERY_ID, {
      type: 'raster',
      tiles: [absoluteApiUrl(item.tiles)],
      tileSize: 256,
      bounds: item.bounds as BBox,
      maxzoom: 22,
    });
    (map.getSource(IMAGERY_ID) as unknown as { _fieldrxId?: number })._fieldrxId = item.id;
    const before = imageryBeforeId(
      map.getStyle().layers.map((l) => l.id),
      IMAGERY_ID,
    );
    map.addLayer({ id: IMAGERY_ID, type: 'raster', source: IMAGERY_ID, paint: { 'raster-opacity': opacity } }, before);
  } else {
    map.setPaintProperty(IMAGERY_ID, 'raster-opacity', opacity);
  }
}
