import { useMemo } from 'react';
import { asGeoJSON } from '../../lib/geo';
import { EMPTY_FC, headLayers, trackLayers, type TrackStyle } from '../layers';
import { useOverlay } from '../useOverlay';

/** Where a replay stands: position and heading (degrees from north). */
export interface TrackHead {
  lon: number;
  lat: number;
  heading: number;
}

/**
 * A driven or planned path: lines (layer `${id}-line`), optional direction arrows along them
 * (`${id}-arrows`) and an optional current-position arrow (`${id}-head`).
 */
export function Track(
  props: {
    /** Source id and layer-id prefix ('route', 'trail', 'trails', ...). */
    id: string;
    /** Line GeoJSON (e.g. a plan's RouteOut) ... */
    data?: object | null;
    /** ... or paths as coordinate lists (one LineString each; shorter than 2 points skipped). */
    paths?: readonly (readonly [number, number])[][];
    /** The replay position, drawn as a red arrow; null/undefined = none. */
    head?: TrackHead | null;
  } & TrackStyle,
) {
  const { id, data, paths, head, color, width, opacity, arrows } = props;
  const fc = useMemo((): GeoJSON.GeoJSON => {
    if (paths)
      return {
        type: 'FeatureCollection',
        features: paths
          .filter((c) => c.length > 1)
          .map((c) => ({ type: 'Feature', properties: {}, geometry: { type: 'LineString', coordinates: c.map((p) => [p[0], p[1]]) } })),
      };
    return data ? asGeoJSON<GeoJSON.GeoJSON>(data) : EMPTY_FC;
  }, [data, paths]);
  const spec = useMemo(
    () => ({
      id,
      slot: 'track' as const,
      source: { type: 'geojson' as const, data: fc },
      layers: trackLayers(id, { color, width, opacity, arrows }),
    }),
    [id, fc, color, width, opacity, arrows],
  );
  useOverlay(spec);
  const hLon = head?.lon;
  const hLat = head?.lat;
  const hHeading = head?.heading;
  const headSpec = useMemo(() => {
    const data: GeoJSON.GeoJSON =
      hLon != null && hLat != null
        ? { type: 'Feature', properties: { heading: hHeading ?? 0 }, geometry: { type: 'Point', coordinates: [hLon, hLat] } }
        : EMPTY_FC;
    return { id: `${id}-head`, slot: 'point' as const, source: { type: 'geojson' as const, data }, layers: headLayers(`${id}-head`) };
  }, [id, hLon, hLat, hHeading]);
  useOverlay(head === undefined ? null : headSpec);
  return null;
}
