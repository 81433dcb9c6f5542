import { useMemo } from 'react';
import { closeRing, type Ring } from '../../lib/geo';
import { holeLayers } from '../layers';
import { useOverlay } from '../useOverlay';

/** Holes cut out of a boundary being drawn (layers `${id}-fill`, `${id}-line`, id default 'holes'). */
export function Holes(props: { rings: readonly Ring[]; id?: string }) {
  const id = props.id ?? 'holes';
  const spec = useMemo(
    () => ({
      id,
      slot: 'area' as const,
      source: {
        type: 'geojson' as const,
        data: {
          type: 'FeatureCollection' as const,
          features: props.rings.map((h) => ({
            type: 'Feature' as const,
            properties: {},
            geometry: { type: 'Polygon' as const, coordinates: [closeRing(h)] },
          })),
        },
      },
      layers: holeLayers(id),
    }),
    [id, props.rings],
  );
  useOverlay(spec);
  return null;
}
