import { useEffect, useMemo } from 'react';
import { pointsFC, problemLayers } from '../layers';
import { useMap } from '../context';
import { useOverlay } from '../useOverlay';

/**
 * Red rings where input was refused (layer `problems` unless `id` is given), kept above
 * every other layer including the drawing tool's. With `focus`, the map jumps to the first
 * point whenever it changes (zoom at least 15).
 */
export function Problems(props: {
  /** [lon, lat] points; null/undefined entries are skipped. */
  points: readonly (readonly [number, number] | null | undefined)[];
  /** Jump to the first point when it changes. */
  focus?: boolean;
  id?: string;
}) {
  const id = props.id ?? 'problems';
  const key = JSON.stringify(props.points);
  // eslint-disable-next-line react-hooks/exhaustive-deps
  const data = useMemo(() => pointsFC(props.points), [key]);
  const spec = useMemo(
    () => ({ id, slot: 'top' as const, source: { type: 'geojson' as const, data }, layers: problemLayers(id) }),
    [id, data],
  );
  useOverlay(spec);
  const map = useMap();
  const first = props.points.find((p) => p != null);
  const f0 = first?.[0];
  const f1 = first?.[1];
  useEffect(() => {
    if (!map || !props.focus || f0 == null || f1 == null) return;
    map.jumpTo({ center: [f0, f1], zoom: Math.max(map.getZoom(), 15) });
  }, [map, props.focus, f0, f1]);
  return null;
}
