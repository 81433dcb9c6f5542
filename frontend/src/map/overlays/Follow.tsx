import { useEffect, useRef } from 'react';
import { useMap } from '../context';
import { outsideVisible, visiblePadding } from '../padding';

/**
 * Keeps one point (the machine the user picked in a list) in view: the map centres on it
 * when it is picked, zoomed in to at least `minZoom` (a fleet fitted to machines far
 * apart is shown at a zoom where a machine's cells are smaller than a pixel), then pans
 * only when the point nears the edge of the visible map, so the user's zoom is kept and
 * the map does not jump on every position.
 */
export function Follow(props: {
  /** What is followed (e.g. the machine id): a new key centres the map at once. */
  followKey: string | number | null;
  point: [number, number] | null;
  /** CSS selector of an element over part of the map (see `FitBounds`). */
  avoid?: string;
  /** Pixels from the visible edge at which the map pans (default 40). */
  margin?: number;
  /** Zoom the map is brought in to when a point is picked (default 16); never out. */
  minZoom?: number;
}) {
  const map = useMap();
  const centred = useRef<string | number | null>(null);
  const { followKey, point, avoid, margin, minZoom } = props;
  const lon = point?.[0];
  const lat = point?.[1];
  useEffect(() => {
    if (!map || followKey == null || lon == null || lat == null) {
      if (followKey == null) centred.current = null;
      return;
    }
    const el = avoid ? document.querySelector(avoid) : null;
    const box = map.getContainer().getBoundingClientRect();
    const padding = visiblePadding(box, el?.getBoundingClientRect() ?? null, 0);
    const p = map.project([lon, lat]);
    if (centred.current !== followKey) {
      map.jumpTo({ center: [lon, lat], zoom: Math.max(map.getZoom(), minZoom ?? 16), padding });
      centred.current = followKey;
    } else if (outsideVisible(box, padding, p.x, p.y, margin ?? 40)) {
      map.jumpTo({ center: [lon, lat], padding });
    }
  }, [map, followKey, lon, lat, avoid, margin, minZoom]);
  return null;
}
