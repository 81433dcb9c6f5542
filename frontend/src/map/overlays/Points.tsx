import { useMemo } from 'react';
import * as maplibregl from 'maplibre-gl';
import { asGeoJSON } from '../../lib/geo';
import { EMPTY_FC, pointLayers } from '../layers';
import { useMap } from '../context';
import { useLayerClick, useOverlay } from '../useOverlay';

/**
 * Sample points (e.g. soil samples): circles coloured by `color` (a colour or an expression
 * such as `stepExpression('n_pct', breaks, colors)`), layer `id`. `popup` turns a click into
 * a popup with the HTML it returns.
 */
export function Points(props: {
  /** Source and layer id, e.g. 'soil'. */
  id: string;
  /** Point GeoJSON (e.g. a SampleCollection). */
  data: object | null | undefined;
  color?: unknown;
  /** Circle radius in px (default 7). */
  radius?: number;
  /** HTML shown in a popup on click (escape what you put in); undefined = no popup. */
  popup?: (properties: Record<string, unknown>) => string;
}) {
  const { id, data } = props;
  const color = props.color ?? '#8b4513';
  const radius = props.radius ?? 7;
  const fc = useMemo(() => (data ? asGeoJSON<GeoJSON.GeoJSON>(data) : EMPTY_FC), [data]);
  const colorKey = JSON.stringify(color);
  const spec = useMemo(
    () => ({ id, slot: 'point' as const, source: { type: 'geojson' as const, data: fc }, layers: pointLayers(id, color, radius) }),
    // eslint-disable-next-line react-hooks/exhaustive-deps
    [id, fc, colorKey, radius],
  );
  useOverlay(spec);
  const map = useMap();
  const popup = props.popup;
  useLayerClick(
    id,
    popup &&
      ((f, e) => {
        if (map) new maplibregl.Popup().setLngLat(e.lngLat).setHTML(popup(f.properties ?? {})).addTo(map);
      }),
  );
  return null;
}
