import { useMemo } from 'react';
import { asGeoJSON } from '../../lib/geo';
import { EMPTY_FC, fieldBoundaryLayers } from '../layers';
import { useLayerClick, useOverlay } from '../useOverlay';

/**
 * Field boundaries in the one field style (`FIELD_STYLE`): one field, a field collection or
 * any polygon GeoJSON. Layers `${id}-fill` (unless `fill={false}`) and `${id}-line`.
 */
export function FieldBoundary(props: {
  /** A FieldFeature, a FieldCollection or polygon GeoJSON; null/undefined draws nothing (yet). */
  data: object | null | undefined;
  /** Source id and layer-id prefix; default 'field'. */
  id?: string;
  /** Fill the area (default true); false draws the outline only, e.g. over a coloured grid. */
  fill?: boolean;
  /** Clicking a field calls this with its id (`properties.id`, else the feature id); needs `fill`. */
  onClick?: (fieldId: number) => void;
}) {
  const id = props.id ?? 'field';
  const fill = props.fill ?? true;
  const spec = useMemo(
    () => ({
      id,
      slot: 'line' as const,
      source: { type: 'geojson' as const, data: props.data ? asGeoJSON<GeoJSON.GeoJSON>(props.data) : EMPTY_FC },
      layers: fieldBoundaryLayers(id, fill),
    }),
    [id, fill, props.data],
  );
  useOverlay(spec);
  const onClick = props.onClick;
  useLayerClick(
    `${id}-fill`,
    onClick &&
      ((f) => {
        const fid = f.properties?.id ?? f.id;
        if (fid != null) onClick(Number(fid));
      }),
  );
  return null;
}
