/**
 * Job kinds: prescription map (seed 001), sensor-based topdressing (seed 000),
 * seeding with depth control (seed 002). The server owns the defaults and the validation
 * (GET /jobs/kinds, fieldrx_edge.jobkinds.settings); this module shapes the forms: every
 * input with its unit and the paper's value named as such, and the body sent.
 */
import type { Schemas } from '../api/client';

export type JobKind = NonNullable<Schemas['JobIn']['kind']>;

export const KIND_LABELS: Record<JobKind, string> = {
  prescription_map: 'Prescription map (seed 001)',
  ndvi_topdress: 'Sensor-based topdressing, NDVI (seed 000)',
  seeding_depth: 'Seeding with depth control (seed 002)',
};

/** One form input: dotted settings path, label, unit, the paper's default and its source. */
export interface SettingField {
  path: string;
  label: string;
  unit: string;
  paper: number | string | boolean;
  source: string;
  step?: number;
  options?: string[];
}

export const NDVI_FIELDS: SettingField[] = [
  { path: 'rate_curve.ndvi_lo', label: 'Low NDVI', unit: 'NDVI', paper: 0.24, source: 'seed 000', step: 0.01 },
  { path: 'rate_curve.rate_at_lo_kg_ha', label: 'Rate at low NDVI', unit: 'kg/ha', paper: 375, source: 'seed 000' },
  { path: 'rate_curve.ndvi_hi', label: 'High NDVI', unit: 'NDVI', paper: 0.65, source: 'seed 000', step: 0.01 },
  { path: 'rate_curve.rate_at_hi_kg_ha', label: 'Rate at high NDVI', unit: 'kg/ha', paper: 180, source: 'seed 000' },
  { path: 'sensors.count', label: 'Canopy sensors', unit: 'sensors', paper: 4, source: 'seed 000 (ACS-430)' },
  { path: 'sensors.layout', label: 'Sensor layout', unit: '', paper: 'distributed', source: 'seed 000 Table 1', options: ['distributed', 'over_row'] },
  { path: 'sensors.height_m', label: 'Sensor height', unit: 'm', paper: 0.88, source: 'seed 000', step: 0.01 },
  { path: 'window', label: 'Sliding window', unit: 'samples', paper: 15, source: 'seed 000' },
  { path: 'controller.name', label: 'Shaft controller', unit: '', paper: 'isp', source: 'seed 000 eq. 11-12', options: ['isp', 'incremental_pid', 'ladrc'] },
  { path: 'sensor_hold_s', label: 'Hold last good reading', unit: 's', paper: 1.0, source: 'FieldRx', step: 0.1 },
  { path: 'restrict_to_boundary', label: 'Only inside the field boundary', unit: '', paper: true, source: 'FieldRx', options: ['true', 'false'] },
];

export const DEPTH_FIELDS: SettingField[] = [
  { path: 'target_depth_mm', label: 'Target depth', unit: 'mm', paper: 30, source: 'seed 002' },
  { path: 'sensor_calibration.slope_mm_per_mv', label: 'Sensor slope', unit: 'mm/mV', paper: -0.065, source: 'seed 002 eq. 13', step: 0.001 },
  { path: 'sensor_calibration.intercept_mm', label: 'Sensor intercept', unit: 'mm', paper: 270.35, source: 'seed 002 eq. 13', step: 0.01 },
  { path: 'sensor_calibration.signal_min_mv', label: 'Valid signal from', unit: 'mV', paper: 2628, source: 'seed 002' },
  { path: 'sensor_calibration.signal_max_mv', label: 'Valid signal to', unit: 'mV', paper: 4356, source: 'seed 002' },
  { path: 'controller.name', label: 'Depth controller', unit: '', paper: 'fuzzy_pid', source: 'seed 002 sec. 2.3', options: ['fuzzy_pid', 'pid'] },
  { path: 'actuator_speed_mm_s', label: 'Cylinder speed', unit: 'mm/s', paper: 50, source: 'seed 002 sec. 4.1' },
  { path: 'alert_window_m', label: 'Alert window', unit: 'm', paper: 50, source: 'FieldRx' },
  { path: 'alert_min_qualified_pct', label: 'Alert below qualified', unit: '%', paper: 90, source: 'FieldRx' },
  { path: 'sensor_hold_s', label: 'Hold last good reading', unit: 's', paper: 0.5, source: 'FieldRx', step: 0.1 },
];

export function fieldsOf(kind: JobKind): SettingField[] {
  return kind === 'ndvi_topdress' ? NDVI_FIELDS : kind === 'seeding_depth' ? DEPTH_FIELDS : [];
}

/**
 * Partial settings from the form's text values: only the inputs the user changed from the
 * paper's value are sent (the server fills in the rest and names any bad one).
 */
export function settingsBody(kind: JobKind, values: Record<string, string>): Record<string, unknown> {
  const out: Record<string, unknown> = {};
  for (const f of fieldsOf(kind)) {
    const raw = values[f.path];
    if (raw == null || raw === '' || raw === String(f.paper)) continue;
    const v: unknown = typeof f.paper === 'number' ? Number(raw) : typeof f.paper === 'boolean' ? raw === 'true' : raw;
    const parts = f.path.split('.');
    let obj = out;
    for (const p of parts.slice(0, -1)) obj = (obj[p] ??= {}) as Record<string, unknown>;
    obj[parts[parts.length - 1]] = v;
  }
  return out;
}

/** POST /jobs body for any kind. */
export function jobBody(
  kind: JobKind,
  ids: { prescriptionId?: string; version?: string; planId?: string; machineId: string },
  values: Record<string, string> = {},
): Schemas['JobIn'] {
  if (kind === 'prescription_map') {
    return {
      prescription_id: Number(ids.prescriptionId),
      prescription_version: ids.version ? Number(ids.version) : undefined,
      machine_id: Number(ids.machineId),
    };
  }
  return { kind, plan_id: Number(ids.planId), machine_id: Number(ids.machineId), settings: settingsBody(kind, values) };
}

/** The keys of a plan the job forms' plan picker shows. */
export interface PlanChoice {
  id: number;
  params: { swath_width_m: number; cell_length_m: number };
  n_cells: number;
  created_at?: string | null;
}

/** A plan in words for a picker: "Plan 12 · 3.6 m swath, 5 m cells · 84 cells · 2026-11-28". */
export function planLabel(p: PlanChoice): string {
  const day = p.created_at ? ` · ${p.created_at.slice(0, 10)}` : '';
  return `Plan ${p.id} · ${p.params.swath_width_m} m swath, ${p.params.cell_length_m} m cells · ${p.n_cells} cells${day}`;
}

/** Seed 000's NDVI -> rate line through two points, clamped between them (the preview). */
export function ndviRate(ndvi: number, lo: number, rateLo: number, hi: number, rateHi: number): number {
  if (!(hi > lo)) return NaN;
  const t = Math.min(1, Math.max(0, (ndvi - lo) / (hi - lo)));
  return rateLo + t * (rateHi - rateLo);
}

/** Preview rows at NDVI 0.2 .. 0.7 in steps of 0.1 for the form's curve values. */
export function ndviPreview(values: Record<string, string>): { ndvi: number; rate: number }[] {
  const g = (p: string, d: number) => (values[p] != null && values[p] !== '' ? Number(values[p]) : d);
  const lo = g('rate_curve.ndvi_lo', 0.24);
  const hi = g('rate_curve.ndvi_hi', 0.65);
  const rl = g('rate_curve.rate_at_lo_kg_ha', 375);
  const rh = g('rate_curve.rate_at_hi_kg_ha', 180);
  return [0.2, 0.3, 0.4, 0.5, 0.6, 0.7].map((n) => ({ ndvi: n, rate: ndviRate(n, lo, rl, hi, rh) }));
}

/** GB/T 20865 qualified band: +-10 mm at a target of 30 mm or more, +-5 mm below. */
export function qualifiedBand(targetMm: number): [number, number] {
  const tol = targetMm >= 30 ? 10 : 5;
  return [targetMm - tol, targetMm + tol];
}

export interface ShaftBand {
  speed_kmh: number;
  n: number;
  theoretical_rpm?: number;
  monitored_rpm?: number;
  relative_error_pct?: number;
}
export interface DepthBand {
  speed_kmh: [number, number];
  n: number;
  mean_mm?: number;
  qualified_pct?: number;
  sd_mm?: number;
  cv_pct?: number;
}

/** The value a kind's map colours cells by. */
export function cellValue(kind: JobKind, view: string, cell: Record<string, unknown>): number | null {
  const key =
    kind === 'ndvi_topdress' ? (view === 'rate' ? 'applied_rate_kg_ha' : 'ndvi') : view === 'qualified' ? 'qualified_pct' : 'depth_mm';
  const v = cell[key];
  return typeof v === 'number' && Number.isFinite(v) ? v : null;
}
