/**
 * Layer declarations of the overlay components, one home per look: the field boundary has
 * one style everywhere ("declared once with one style"), the cell grid one set of
 * layers for plans, prescriptions, as-applied and sensor maps. Pure (no map), unit-tested.
 */
import type * as maplibregl from 'maplibre-gl';
import type { FleetMachine } from '../lib/fleet';
import { statusColor } from '../lib/colors';
import type { OverlayLayer } from './overlay';

/** The one field-boundary style (Fields, field detail, plan, prescription, reports, fleet). */
export const FIELD_STYLE = { fill: '#4c9a2a', fillOpacity: 0.25, line: '#2d5e16', lineWidth: 2 } as const;

/** `${id}-fill` (when `fill`) and `${id}-line`. */
export function fieldBoundaryLayers(id: string, fill: boolean): OverlayLayer[] {
  const line: OverlayLayer = {
    id: `${id}-line`,
    type: 'line',
    paint: { 'line-color': FIELD_STYLE.line, 'line-width': FIELD_STYLE.lineWidth },
  };
  if (!fill) return [line];
  return [
    { id: `${id}-fill`, type: 'fill', paint: { 'fill-color': FIELD_STYLE.fill, 'fill-opacity': FIELD_STYLE.fillOpacity } },
    line,
  ];
}

/** Plan shading: swath parity, so the back-and-forth order is visible. */
export const PLAN_CELL_COLOR = ['case', ['==', ['%', ['to-number', ['get', 'swath'], 0], 2], 0], '#9ccc65', '#c5e1a5'];

/** Outline of cells edited by hand: apart from every rate colour, so an edit never reads as a class. */
export const EDITED_COLOR = '#e6007e';

/** Cells whose `flags` (comma-joined names) say a cell or zone edit set their rate. */
const EDITED_FILTER: maplibregl.FilterSpecification = [
  'any',
  ['in', 'manual', ['to-string', ['get', 'flags']]],
  ['in', 'zone', ['to-string', ['get', 'flags']]],
];

export interface CellGridStyle {
  /** Fill colour: a MapLibre expression (e.g. `stepExpression(...)`) or a colour; default the plan shading. */
  color?: unknown;
  /** Fill opacity; default 0.85 with a colour, 0.6 for the plan shading. */
  opacity?: number;
  /** Thin cell edges from z14 (default: on for the plan shading only). */
  outline?: boolean;
  /** Red outline on cells the implement cannot meter (property `clamped`). */
  clamped?: boolean;
  /** Dashed outline on cells edited by hand (property `flags` holds `manual` or `zone`). */
  edited?: boolean;
  /** Black outline on this cell (`seq`); -1 / null = none. The layer exists whenever this key is given. */
  selectedSeq?: number | null;
  /** The vector-tile source layer ('cells'); undefined for GeoJSON cells. */
  sourceLayer?: string;
}

/** `${id}-fill`, then as asked `${id}-line`, `${id}-clamped`, `${id}-edited`, `${id}-selected`. */
export function cellGridLayers(id: string, s: CellGridStyle): OverlayLayer[] {
  const sl = s.sourceLayer ? { 'source-layer': s.sourceLayer } : {};
  const plan = s.color === undefined;
  const out: OverlayLayer[] = [
    {
      id: `${id}-fill`,
      type: 'fill',
      ...sl,
      paint: { 'fill-color': (plan ? PLAN_CELL_COLOR : s.color) as never, 'fill-opacity': s.opacity ?? (plan ? 0.6 : 0.85) },
    },
  ];
  if (s.outline ?? plan)
    out.push({ id: `${id}-line`, type: 'line', ...sl, minzoom: 14, paint: { 'line-color': '#33691e', 'line-width': 0.5 } });
  if (s.clamped)
    out.push({
      id: `${id}-clamped`,
      type: 'line',
      ...sl,
      filter: ['==', ['get', 'clamped'], true],
      paint: { 'line-color': '#d7263d', 'line-width': 2 },
    });
  if (s.edited)
    out.push({
      id: `${id}-edited`,
      type: 'line',
      ...sl,
      filter: EDITED_FILTER,
      paint: { 'line-color': EDITED_COLOR, 'line-width': 2, 'line-dasharray': [2, 1] },
    });
  if ('selectedSeq' in s)
    out.push({
      id: `${id}-selected`,
      type: 'line',
      ...sl,
      filter: ['==', ['get', 'seq'], s.selectedSeq ?? -1],
      paint: { 'line-color': '#000', 'line-width': 3 },
    });
  return out;
}

export interface TrackStyle {
  color?: string;
  width?: number;
  opacity?: number;
  /** Direction arrows along the line. */
  arrows?: boolean;
}

/** `${id}-line` and (with arrows) `${id}-arrows`: the arrow icon points up, line placement turns it along the line. */
export function trackLayers(id: string, s: TrackStyle): OverlayLayer[] {
  const color = s.color ?? '#1e3a8a';
  const out: OverlayLayer[] = [
    {
      id: `${id}-line`,
      type: 'line',
      paint: { 'line-color': color, 'line-width': s.width ?? 1.5, 'line-opacity': s.opacity ?? 1 },
    },
  ];
  if (s.arrows)
    out.push({
      id: `${id}-arrows`,
      type: 'symbol',
      layout: {
        'symbol-placement': 'line',
        'symbol-spacing': 60,
        'icon-image': 'arrow',
        'icon-rotate': 90,
        'icon-size': 0.45,
        'icon-rotation-alignment': 'map',
        'icon-allow-overlap': true,
      },
      paint: { 'icon-color': color },
    });
  return out;
}

/** The current position of a replay: a red arrow turned to property `heading`. */
export function headLayers(id: string): OverlayLayer[] {
  return [
    {
      id,
      type: 'symbol',
      layout: {
        'icon-image': 'arrow',
        'icon-rotate': ['get', 'heading'],
        'icon-rotation-alignment': 'map',
        'icon-size': 0.8,
        'icon-allow-overlap': true,
      },
      paint: { 'icon-color': '#d7263d', 'icon-halo-color': '#fff', 'icon-halo-width': 2 },
    },
  ];
}

/** `machines-dot` (status colour) and `machines-heading` (white arrow when the heading is known). */
export function machineLayers(): OverlayLayer[] {
  return [
    {
      id: 'machines-dot',
      type: 'circle',
      paint: { 'circle-radius': 11, 'circle-color': ['get', 'color'], 'circle-stroke-color': '#fff', 'circle-stroke-width': 2 },
    },
    {
      id: 'machines-heading',
      type: 'symbol',
      filter: ['==', ['get', 'has_heading'], true],
      layout: {
        'icon-image': 'arrow',
        'icon-rotate': ['get', 'heading'],
        'icon-rotation-alignment': 'map',
        'icon-size': 0.5,
        'icon-allow-overlap': true,
      },
      paint: { 'icon-color': '#ffffff' },
    },
  ];
}

/** Machines with a position as points (id = machine_id), coloured by status. */
export function machinesGeoJSON(
  machines: Iterable<Pick<FleetMachine, 'machine_id' | 'lon' | 'lat' | 'heading_deg' | 'status'>>,
): GeoJSON.FeatureCollection {
  return {
    type: 'FeatureCollection',
    features: [...machines]
      .filter((m) => m.lon != null && m.lat != null)
      .map((m) => ({
        type: 'Feature',
        id: m.machine_id,
        properties: {
          machine_id: m.machine_id,
          heading: m.heading_deg ?? 0,
          color: statusColor(m.status),
          has_heading: m.heading_deg != null,
        },
        geometry: { type: 'Point', coordinates: [m.lon as number, m.lat as number] },
      })),
  };
}

/** Red rings where an input was refused (a self-intersection, a server-reported location). */
export function problemLayers(id: string): OverlayLayer[] {
  return [
    {
      id,
      type: 'circle',
      paint: {
        'circle-radius': 14,
        'circle-color': 'rgba(215, 38, 61, 0.35)',
        'circle-stroke-color': '#d7263d',
        'circle-stroke-width': 3,
      },
    },
  ];
}

/** Sample points (soil samples) coloured by an expression. */
export function pointLayers(id: string, color: unknown, radius: number): OverlayLayer[] {
  return [
    {
      id,
      type: 'circle',
      paint: { 'circle-radius': radius, 'circle-color': color as never, 'circle-stroke-color': '#222', 'circle-stroke-width': 1.5 },
    },
  ];
}

/** Holes cut out of a boundary being drawn: white veil, dashed red edge. */
export function holeLayers(id: string): OverlayLayer[] {
  return [
    { id: `${id}-fill`, type: 'fill', paint: { 'fill-color': '#ffffff', 'fill-opacity': 0.7 } },
    { id: `${id}-line`, type: 'line', paint: { 'line-color': '#b00020', 'line-width': 2, 'line-dasharray': [2, 1] } },
  ];
}

export const EMPTY_FC: GeoJSON.FeatureCollection = { type: 'FeatureCollection', features: [] };

/** Points as a FeatureCollection (null entries skipped). */
export function pointsFC(points: readonly (readonly [number, number] | null | undefined)[]): GeoJSON.FeatureCollection {
  return {
    type: 'FeatureCollection',
    features: points
      .filter((p): p is readonly [number, number] => p != null)
      .map((p) => ({ type: 'Feature', properties: {}, geometry: { type: 'Point', coordinates: [p[0], p[1]] } })),
  };
}
