/**
 * Plan and prescription grids from the server's vector tiles (source-layer
 * "cells"). One GeoJSON source with 50k polygons took ~8 s to render in
 * software WebGL (STACK.md); tiles only carry what is on screen.
 */
import type * as maplibregl from 'maplibre-gl';
import { cellGridLayers, trackLayers } from './layers';
import type { OverlayLayer } from './overlay';
import { absoluteApiUrl } from './setup';

export const GRID_MINZOOM = 8;
// Detail tiles (one feature per cell) start where a cell is ~2 px wide: z17 for 2.3 m cells.
export const GRID_MAXZOOM = 19;

export function planTilesUrl(planId: number): string {
  return absoluteApiUrl(`/api/v1/tiles/plans/${planId}/{z}/{x}/{y}.mvt`);
}

export function rxTilesUrl(rxId: number, version: number): string {
  return absoluteApiUrl(`/api/v1/tiles/prescriptions/${rxId}/${version}/{z}/{x}/{y}.mvt`);
}

/** @deprecated use `<CellGrid tiles>` (it adds, times and removes the source itself). */
export function replaceVectorSource(map: maplibregl.Map, id: string, tilesUrl: string, layers: maplibregl.LayerSpecification[]) {
  for (const l of layers) if (map.getLayer(l.id)) map.removeLayer(l.id);
  if (map.getSource(id)) map.removeSource(id);
  map.addSource(id, {
    type: 'vector',
    tiles: [tilesUrl],
    minzoom: GRID_MINZOOM,
    maxzoom: GRID_MAXZOOM,
    promoteId: { cells: 'seq' },
  });
  for (const l of layers) map.addLayer(l);
  // Time from adding the source to the first idle frame (all visible tiles drawn),
  // read by tests/e2e/perf_grid.mjs.
  const t0 = performance.now();
  const perf = (window.__fieldrxPerf ??= {});
  perf[id] = { addedAt: t0, idleMs: null };
  map.once('idle', () => {
    if (perf[id]?.addedAt === t0) perf[id].idleMs = performance.now() - t0;
  });
}


const withSource = (source: string, layers: OverlayLayer[]) =>
  layers.map((l) => ({ ...l, source }) as maplibregl.LayerSpecification);

/** @deprecated use `<CellGrid>`: plan grid, cells shaded by swath parity. */
export function planGridLayers(source: string): maplibregl.LayerSpecification[] {
  return withSource(source, cellGridLayers(source, { sourceLayer: 'cells' }));
}

/** @deprecated use `<CellGrid color clamped selectedSeq>`: prescription grid coloured by rate. */
export function rxGridLayers(source: string, colorExpr: unknown): maplibregl.LayerSpecification[] {
  return withSource(source, cellGridLayers(source, { color: colorExpr, clamped: true, selectedSeq: null, sourceLayer: 'cells' }));
}

/** @deprecated use `<Track arrows>`: route line with arrows along it. */
export function addRouteLayers(map: maplibregl.Map, source: string): void {
  for (const l of withSource(source, trackLayers(source, { arrows: true }))) map.addLayer(l);
}

/** Distinct features of a vector source currently loaded (deduplicated by seq). */
export function loadedCells(map: maplibregl.Map, source: string): Map<number, Record<string, unknown>> {
  const out = new Map<number, Record<string, unknown>>();
  if (!map.getSource(source)) return out;
  for (const f of map.querySourceFeatures(source, { sourceLayer: 'cells' })) {
    const seq = Number(f.properties?.seq);
    if (Number.isFinite(seq) && !out.has(seq)) out.set(seq, f.properties ?? {});
  }
  return out;
}
