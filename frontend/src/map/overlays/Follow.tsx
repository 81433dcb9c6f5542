import { useEffect, useRef } from 'react';
import { useMap } from '../context';
import { outsideVisible, visiblePadding } from '../padding';

/**
 * Keeps one point (the machine the user picked in a list) in view: the map centres on it
 * when it is picked, then pans only when the point nears the edge of the visible map, so
 * the user's zoom is kept and the map does not jump on every position.
 */
export function Follow(props: {
  /** What is followed (e.g. the machine id): a new key centres the map at once. */
  followKey: string | number | null;
  point: [number, number] | null;
  /** CSS selector of an element over part of the map (see `FitBounds`). */
  avoid?: string;
  /** Pixels from the visible edge at which the map pans (default 40). */
  margin?: number;
}) {
  const map = useMap();
  const centred = useRef<string | number | null>(null);
  const { followKey, point, avoid, margin } = props;
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
    if (centred.current !== followKey || outsideVisible(box, padding, p.x, p.y, margin ?? 40)) {
      map.jumpTo({ center: [lon, lat], padding });
      centred.current = followKey;
    }
  }, [map, followKey, lon, lat, avoid, margin]);
  return null;
}
