import { useEffect, useMemo, useRef } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { GRID_MAXZOOM, GRID_MINZOOM } from '../grid';
import { cellGridLayers, EMPTY_FC } from '../layers';
import { useMap } from '../context';
import { useLayerClick, useOverlay } from '../useOverlay';

declare global {
  interface Window {
    /** Time from adding a grid source to its first idle frame, by source id (tests/e2e/perf_grid.mjs). */
    __fieldrxPerf?: Record<string, { addedAt: number; idleMs: number | null }>;
  }
}

/**
 * A cell grid: a plan, a prescription (coloured by rate), an as-applied or sensor map.
 * From the server's vector tiles (`tiles`, source-layer "cells", features promoted by `seq`)
 * or from GeoJSON cells (`data`). Layers `${id}-fill` and, as asked, `${id}-line`,
 * `${id}-clamped`, `${id}-edited`, `${id}-selected`. A new `tiles` URL re-creates the source (and re-times
 * the first frame in `window.__fieldrxPerf[id]`); a new `refreshKey` re-requests the same
 * tiles in place (live as-applied data) without removing the layers (not the key the source
 * was created with: those tiles are being loaded already).
 */
export function CellGrid(props: {
  /** Source id and layer-id prefix ('grid', 'rx', 'job', ...). */
  id: string;
  /** Vector-tile URL template, e.g. `planTilesUrl(planId)`, `rxTilesUrl(rxId, version)`. */
  tiles?: string;
  /** GeoJSON cells instead of tiles (small grids, e.g. sensor-job maps). */
  data?: GeoJSON.FeatureCollection | null;
  /** Fill colour expression (e.g. `stepExpression('rate_kg_ha', breaks, colors)`); default the plan's swath shading. */
  color?: unknown;
  /** Fill opacity (default 0.85 with a colour, 0.6 for the plan shading). */
  opacity?: number;
  /** Cell edges from z14 (default on for the plan shading only). */
  outline?: boolean;
  /** Red outline on clamped cells. */
  clamped?: boolean;
  /** Dashed outline on cells edited by hand (`${id}-edited`). */
  edited?: boolean;
  /** Outline this cell (`seq`); pass null for none. Omit the prop to have no selection layer. */
  selectedSeq?: number | null;
  /** Changing it re-requests the tiles (appends `v=<key>`) without re-creating the layers. */
  refreshKey?: number | string;
  /** Click on a cell: its properties (`seq`, `rate_kg_ha`, `n_cells`, ...). */
  onClick?: (properties: Record<string, unknown>, e: maplibregl.MapLayerMouseEvent) => void;
}) {
  const { id, tiles, data, color, opacity, outline, clamped, edited } = props;
  const hasSel = 'selectedSeq' in props;
  const sel = props.selectedSeq ?? null;
  const spec = useMemo(() => {
    if (!tiles && data === undefined) return null;
    const source: maplibregl.SourceSpecification = tiles
      ? { type: 'vector', tiles: [tiles], minzoom: GRID_MINZOOM, maxzoom: GRID_MAXZOOM, promoteId: { cells: 'seq' } }
      : { type: 'geojson', data: data ?? EMPTY_FC };
    const style = { color, opacity, outline, clamped, edited, sourceLayer: tiles ? 'cells' : undefined };
    return {
      id,
      slot: 'grid' as const,
      source,
      layers: cellGridLayers(id, hasSel ? { ...style, selectedSeq: sel } : style),
    };
  }, [id, tiles, data, color, opacity, outline, clamped, edited, hasSel, sel]);
  const { refreshKey } = props;
  // The key the source was (re)created with: its tiles are fresh, no need to ask again.
  const keyAtAdd = useRef(refreshKey);
  useOverlay(spec, (map) => {
    keyAtAdd.current = refreshKey;
    const t0 = performance.now();
    const perf = (window.__fieldrxPerf ??= {});
    perf[id] = { addedAt: t0, idleMs: null };
    map.once('idle', () => {
      if (perf[id]?.addedAt === t0) perf[id].idleMs = performance.now() - t0;
    });
  });
  const map = useMap();
  useEffect(() => {
    if (!map || !tiles || refreshKey === undefined || refreshKey === keyAtAdd.current) return;
    keyAtAdd.current = refreshKey;
    const src = map.getSource(id) as maplibregl.VectorTileSource | undefined;
    src?.setTiles([`${tiles}${tiles.includes('?') ? '&' : '?'}v=${refreshKey}`]);
  }, [map, id, tiles, refreshKey]);
  const onClick = props.onClick;
  useLayerClick(`${id}-fill`, onClick && ((f, e) => onClick(f.properties ?? {}, e)));
  return null;
}
