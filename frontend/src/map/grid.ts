/**
 * Plan and prescription grids from the server's vector tiles (source-layer
 * "cells"). One GeoJSON source with 50k polygons took ~8 s to render in
 * software WebGL (docs/architecture.md, "Stack notes"); tiles only carry what is on screen.
 */
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
