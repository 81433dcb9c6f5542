import { useEffect, useRef } from 'react';
import type { BBox } from '../../lib/geo';
import { useMap } from '../context';
import { visiblePadding } from '../padding';
import { fitTo } from '../setup';

/**
 * Fits the map to `bbox` whenever its value changes (not on every render); with `once`, only
 * to the first non-null one (e.g. the fleet's first positions), so later pans are kept.
 */
export function FitBounds(props: {
  bbox: BBox | null | undefined;
  /** Pixels around the box (default 40). */
  padding?: number;
  /** Never zoom in further than this (default 18). */
  maxZoom?: number;
  once?: boolean;
  /**
   * CSS selector of an element that may lie over the map (the side panel on a tablet, a
   * sheet on a phone): the box is fitted into the part of the map it leaves visible.
   */
  avoid?: string;
}) {
  const map = useMap();
  const done = useRef(false);
  const key = props.bbox ? props.bbox.join(',') : '';
  const { padding, maxZoom, once, avoid } = props;
  useEffect(() => {
    if (!map || !key || (once && done.current)) return;
    const el = avoid ? document.querySelector(avoid) : null;
    const pad = visiblePadding(map.getContainer().getBoundingClientRect(), el?.getBoundingClientRect() ?? null, padding ?? 40);
    fitTo(map, key.split(',').map(Number) as BBox, pad);
    if (maxZoom != null && map.getZoom() > maxZoom) map.setZoom(maxZoom);
    done.current = true;
  }, [map, key, padding, maxZoom, once, avoid]);
  return null;
}
