/** React glue between overlay components and `syncOverlay`: mount, update, unmount. */
import { useEffect, useRef } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { useMap } from './context';
import { syncOverlay, type OverlaySpec } from './overlay';

/**
 * Keep `spec` on the enclosing MapView's map: added on mount (once the map has loaded),
 * updated when `spec` changes (memoise it: a new object each render means a diff each
 * render), removed on unmount. `onAdded` runs whenever the source was (re)created.
 */
export function useOverlay(spec: OverlaySpec | null, onAdded?: (map: maplibregl.Map) => void): void {
  const map = useMap();
  const prev = useRef<OverlaySpec | null>(null);
  const added = useRef(onAdded);
  added.current = onAdded;
  useEffect(() => {
    if (!map) return;
    if (syncOverlay(map, prev.current, spec) === 'added') added.current?.(map);
    prev.current = spec;
  }, [map, spec]);
  useEffect(
    () => () => {
      if (!map || !prev.current) return;
      try {
        syncOverlay(map, prev.current, null);
      } catch {
        /* the map was removed first: its layers went with it */
      }
      prev.current = null;
    },
    [map],
  );
}

/**
 * Click (and pointer cursor) on a layer: `onClick` gets the top feature under the pointer.
 * Registered after the overlay's own effect, so the layer exists.
 */
export function useLayerClick(
  layerId: string,
  onClick: ((feature: maplibregl.MapGeoJSONFeature, e: maplibregl.MapLayerMouseEvent) => void) | undefined,
): void {
  const map = useMap();
  const cb = useRef(onClick);
  cb.current = onClick;
  const active = onClick != null;
  useEffect(() => {
    if (!map || !active) return;
    const click = (e: maplibregl.MapLayerMouseEvent) => {
      const f = e.features?.[0];
      if (f) cb.current?.(f, e);
    };
    const enter = () => (map.getCanvas().style.cursor = 'pointer');
    const leave = () => (map.getCanvas().style.cursor = '');
    map.on('click', layerId, click);
    map.on('mouseenter', layerId, enter);
    map.on('mouseleave', layerId, leave);
    return () => {
      map.off('click', layerId, click);
      map.off('mouseenter', layerId, enter);
      map.off('mouseleave', layerId, leave);
    };
  }, [map, layerId, active]);
}
