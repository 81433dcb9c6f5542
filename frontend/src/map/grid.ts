/**
 * Plan and prescription grids from the server's vector tiles (source-layer
 * "cells"). One GeoJSON source with 50k polygons took ~8 s to render in
 * software WebGL (STACK.md); tiles only carry what is on screen.
 */
import type * as maplibregl from 'maplibre-gl';
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

declare global {
  interface Window {
    __fieldrxPerf?: Record<string, { addedAt: number; idleMs: number | null }>;
  }
}

/** Plan grid: cells shaded by swath parity so the back-and-forth order is visible. */
export function planGridLayers(source: string): maplibregl.LayerSpecification[] {
  return [
    {
      id: `${source}-fill`,
      type: 'fill',
      source,
      'source-layer': 'cells',
      paint: {
        'fill-color': ['case', ['==', ['%', ['to-number', ['get', 'swath'], 0], 2], 0], '#9ccc65', '#c5e1a5'],
        'fill-opacity': 0.6,
      },
    },
    {
      id: `${source}-line`,
      type: 'line',
      source,
      'source-layer': 'cells',
      minzoom: 14,
      paint: { 'line-color': '#33691e', 'line-width': 0.5 },
    },
  ];
}

/** Prescription grid coloured by rate (a step expression built from legend breaks). */
export function rxGridLayers(source: string, colorExpr: unknown): maplibregl.LayerSpecification[] {
  return [
    {
      id: `${source}-fill`,
      type: 'fill',
      source,
      'source-layer': 'cells',
      paint: { 'fill-color': colorExpr as never, 'fill-opacity': 0.85 },
    },
    {
      // Clamped cells (the implement cannot meter the computed rate) get a red outline.
      id: `${source}-clamped`,
      type: 'line',
      source,
      'source-layer': 'cells',
      filter: ['==', ['get', 'clamped'], true],
      paint: { 'line-color': '#d7263d', 'line-width': 2 },
    },
    {
      id: `${source}-selected`,
      type: 'line',
      source,
      'source-layer': 'cells',
      filter: ['==', ['get', 'seq'], -1],
      paint: { 'line-color': '#000', 'line-width': 3 },
    },
  ];
}

/** Route line with arrows along it (arrow icon points up; line placement aligns x with the line). */
export function addRouteLayers(map: maplibregl.Map, source: string): void {
  map.addLayer({
    id: `${source}-line`,
    type: 'line',
    source,
    paint: { 'line-color': '#1e3a8a', 'line-width': 1.5 },
  });
  map.addLayer({
    id: `${source}-arrows`,
    type: 'symbol',
    source,
    layout: {
      'symbol-placement': 'line',
      'symbol-spacing': 60,
      'icon-image': 'arrow',
      'icon-rotate': 90,
      'icon-size': 0.45,
      'icon-rotation-alignment': 'map',
      'icon-allow-overlap': true,
    },
    paint: { 'icon-color': '#1e3a8a' },
  });
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
