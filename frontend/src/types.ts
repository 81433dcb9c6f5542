/** Shapes of API responses the UI reads (only the keys it uses; servers may send more). */
import type { AreaGeom } from './lib/geo';

export interface Farm {
  id: number;
  name: string;
  notes?: string | null;
}

export interface FieldProps {
  id: number;
  name: string;
  farm_id: number | null;
  crop?: string | null;
  notes?: string | null;
  area_m2?: number;
  area_ha?: number;
  utm_epsg?: number;
}

export interface FieldFeature {
  type: 'Feature';
  id?: number;
  geometry: AreaGeom;
  properties: FieldProps;
}

export interface FieldCollection {
  type: 'FeatureCollection';
  features: FieldFeature[];
  total?: number;
}

export interface Machine {
  id: number;
  name: string;
  implement_type?: string;
  width_m?: number;
  lag_s?: number;
  calibration?: Record<string, unknown>;
  speed_min_m_s?: number;
  speed_max_m_s?: number;
  antenna_forward_m?: number;
  antenna_lateral_m?: number;
}

export interface Plan {
  id: number;
  field_id: number;
  swath_width_m?: number;
  cell_length_m?: number;
  heading_rule?: string;
  heading_deg?: number | null;
  headland_passes?: number;
  created_at?: string;
  stats?: Record<string, number>;
  [k: string]: unknown;
}

export interface Prescription {
  id: number;
  plan_id: number;
  model?: string;
  params?: Record<string, unknown>;
  version?: number;
  latest_version?: number;
  versions?: { version: number; created_at?: string; note?: string; [k: string]: unknown }[];
  stats?: Record<string, number>;
  [k: string]: unknown;
}

export interface Job {
  id: number;
  prescription_id: number;
  version?: number;
  prescription_version?: number;
  machine_id: number;
  state: string;
  progress?: number | null;
  created_at?: string;
  /** cells with no data / outside the meter range when the job was made, and the sender's confirmation */
  flagged_cells?: number;
  flagged_confirmed?: boolean;
  /** issue 13: prescription_map | ndvi_topdress | seeding_depth; sensor kinds drive plan_id */
  kind?: string;
  plan_id?: number | null;
  settings?: Record<string, unknown>;
  [k: string]: unknown;
}

export interface MachineStatus {
  machine_id: number;
  name?: string;
  lon?: number | null;
  lat?: number | null;
  heading_deg?: number | null;
  speed_filtered_m_s?: number | null;
  status?: string;
  job_id?: number | null;
  progress?: number | null;
  t?: number | string | null;
  [k: string]: unknown;
}

export interface Alert {
  id: number;
  machine_id?: number;
  job_id?: number | null;
  kind?: string;
  message?: string;
  severity?: string;
  created_at?: string;
  acknowledged?: boolean;
  acknowledged_at?: string | null;
  active?: boolean;
  started_at?: string;
  ended_at?: string | null;
  [k: string]: unknown;
}

/** Reads a number from the first key present (servers name stats differently over time). */
export function pick(o: Record<string, unknown> | undefined | null, ...keys: string[]): number | undefined {
  if (!o) return undefined;
  for (const k of keys) {
    const v = o[k];
    if (typeof v === 'number' && Number.isFinite(v)) return v;
  }
  return undefined;
}

/** Unwraps list responses that may be a bare array or {items: [...]} / {results: [...]}. */
export function listOf<T>(r: unknown): T[] {
  if (Array.isArray(r)) return r as T[];
  if (r && typeof r === 'object') {
    const o = r as Record<string, unknown>;
    for (const k of ['items', 'results', 'data', 'jobs', 'machines', 'alerts', 'plans', 'features', 'versions'])
      if (Array.isArray(o[k])) return o[k] as T[];
  }
  return [];
}
