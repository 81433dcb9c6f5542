/**
 * Metering calibration entered on the Machines screen: seed 001 eq. 1,
 * q0 = a * r + b [g/min] for a shaft speed r in r/min, valid for
 * min_rpm <= r <= max_rpm, plus the application lag time (eq. 16).
 * There is no default: every field is measured on the machine.
 */

export interface CalibrationForm {
  slope: string;
  intercept: string;
  minRpm: string;
  maxRpm: string;
  lag: string;
}

export interface LinearCalibration {
  kind: 'linear';
  slope_g_min_per_rpm: number;
  intercept_g_min: number;
  min_rpm: number;
  max_rpm: number;
}

export type CalibrationErrors = Partial<Record<keyof CalibrationForm, string>>;

export const EMPTY_CALIBRATION: CalibrationForm = { slope: '', intercept: '', minRpm: '', maxRpm: '', lag: '' };

const LABELS: Record<keyof CalibrationForm, string> = {
  slope: 'slope a (g/min per r/min)',
  intercept: 'intercept b (g/min)',
  minRpm: 'minimum shaft speed (r/min)',
  maxRpm: 'maximum shaft speed (r/min)',
  lag: 'lag time (s)',
};

function num(v: string): number | null {
  if (v.trim() === '') return null;
  const n = Number(v);
  return Number.isFinite(n) ? n : NaN;
}

/** Checks the form like the server does; returns errors per field, or the API body parts. */
export function validateCalibration(
  f: CalibrationForm,
): { errors: CalibrationErrors; value?: { lag_s: number; calibration: LinearCalibration } } {
  const errors: CalibrationErrors = {};
  const v: Partial<Record<keyof CalibrationForm, number>> = {};
  for (const k of Object.keys(LABELS) as (keyof CalibrationForm)[]) {
    const n = num(f[k]);
    if (n === null) errors[k] = `${LABELS[k]} is required`;
    else if (Number.isNaN(n)) errors[k] = `${LABELS[k]} must be a number`;
    else v[k] = n;
  }
  if (v.slope !== undefined && !(v.slope > 0)) errors.slope = `${LABELS.slope} must be > 0`;
  if (v.minRpm !== undefined && v.minRpm < 0) errors.minRpm = `${LABELS.minRpm} must be >= 0`;
  if (v.lag !== undefined && (v.lag < 0 || v.lag > 30)) errors.lag = `${LABELS.lag} must be 0..30 s`;
  if (v.minRpm !== undefined && v.maxRpm !== undefined && !(v.maxRpm > v.minRpm))
    errors.maxRpm = `maximum shaft speed must be greater than the minimum (${v.minRpm} r/min)`;
  if (!errors.slope && !errors.intercept && !errors.minRpm && v.slope !== undefined && v.intercept !== undefined && v.minRpm !== undefined) {
    const q = v.slope * v.minRpm + v.intercept;
    if (q <= 0) errors.minRpm = `the meter delivers ${q.toFixed(1)} g/min at ${v.minRpm} r/min: raise the minimum shaft speed`;
  }
  if (Object.keys(errors).length) return { errors };
  return {
    errors,
    value: {
      lag_s: v.lag!,
      calibration: {
        kind: 'linear',
        slope_g_min_per_rpm: v.slope!,
        intercept_g_min: v.intercept!,
        min_rpm: v.minRpm!,
        max_rpm: v.maxRpm!,
      },
    },
  };
}

/** Rate in kg/ha that a shaft speed gives (seed 001 eq. 1-2): Q = q0 / (6 L v), v in m/s. */
export function rateAt(cal: LinearCalibration, rpm: number, widthM: number, speedMs: number): number {
  return (cal.slope_g_min_per_rpm * rpm + cal.intercept_g_min) / (6 * widthM * speedMs);
}

/** Shaft speed for a rate (eq. 1-2 inverted): r = (6 Q L v - b) / a. */
export function shaftRpmFor(cal: LinearCalibration, rateKgHa: number, widthM: number, speedMs: number): number {
  return (6 * rateKgHa * widthM * speedMs - cal.intercept_g_min) / cal.slope_g_min_per_rpm;
}

/** Rates the machine can meter at every speed of its range: floor at the slowest, ceiling at the fastest. */
export function meterableRange(
  cal: LinearCalibration,
  widthM: number,
  speedMinMs: number,
  speedMaxMs: number,
): [number, number] {
  return [rateAt(cal, cal.min_rpm, widthM, speedMinMs), rateAt(cal, cal.max_rpm, widthM, speedMaxMs)];
}

/** "q0 = 237.2 r − 404.4 g/min, 30–130 r/min" (or the table form's range). */
export function calibrationText(c: Record<string, unknown> | undefined): string {
  if (!c) return '–';
  if (c.kind === 'table') return `table, ${String(c.min_rpm)}–${String(c.max_rpm)} r/min`;
  const l = c as unknown as LinearCalibration;
  const b = l.intercept_g_min;
  return `q0 = ${l.slope_g_min_per_rpm} r ${b < 0 ? '−' : '+'} ${Math.abs(b)} g/min, ${l.min_rpm}–${l.max_rpm} r/min`;
}

/** The form filled with a stored linear calibration and lag (to edit them). */
export function formOf(c: Record<string, unknown> | undefined, lagS: number | undefined): CalibrationForm {
  const str = (v: unknown) => (typeof v === 'number' ? String(v) : '');
  return {
    slope: str(c?.slope_g_min_per_rpm),
    intercept: str(c?.intercept_g_min),
    minRpm: str(c?.min_rpm),
    maxRpm: str(c?.max_rpm),
    lag: str(lagS),
  };
}
