import { useMemo } from 'react';
import type { BBox } from '../../lib/geo';
import type { ImageryItem } from '../../lib/imagery';
import { absoluteApiUrl } from '../setup';
import { useOverlay } from '../useOverlay';

/** The imagery layer id (one per map). */
export const IMAGERY_ID = 'imagery';

/**
 * One orthophoto / NDVI raster under every data layer (slot 'imagery'), layer and source
 * id 'imagery'. A different `item` replaces the image; a new `opacity` only repaints.
 */
export function Imagery(props: {
  /** The image to show; null shows none. */
  item: ImageryItem | null;
  /** 0..1 */
  opacity: number;
}) {
  const { item, opacity } = props;
  const spec = useMemo(
    () =>
      item
        ? {
            id: IMAGERY_ID,
            slot: 'imagery' as const,
            source: {
              type: 'raster' as const,
              tiles: [absoluteApiUrl(item.tiles)],
              tileSize: 256,
              bounds: item.bounds as BBox,
              maxzoom: 22,
            },
            layers: [{ id: IMAGERY_ID, type: 'raster' as const, paint: { 'raster-opacity': opacity } }],
          }
        : null,
    [item, opacity],
  );
  useOverlay(spec);
  return null;
}
