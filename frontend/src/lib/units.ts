/** Display formatting. SI inside the app; conversion only at the edge (what the user reads). */

export const M2_PER_HA = 10_000;

function num(v: number, digits: number): string {
  return v.toLocaleString('en-US', { minimumFractionDigits: digits, maximumFractionDigits: digits });
}

/** Area in m^2 -> "1,234 m²" below 0.1 ha, else "12.34 ha". */
export function formatArea(m2: number | null | undefined): string {
  if (m2 == null || !Number.isFinite(m2)) return '–';
  if (Math.abs(m2) < 1000) return `${num(m2, 0)} m²`;
  return `${num(m2 / M2_PER_HA, 2)} ha`;
}

export function formatRate(kgHa: number | null | undefined, digits = 1): string {
  if (kgHa == null || !Number.isFinite(kgHa)) return '–';
  return `${num(kgHa, digits)} kg/ha`;
}

/** One decimal below 1000, none above: "150.0", "650,000". */
function amount(v: number): string {
  return num(v, Math.abs(v) >= 1000 ? 0 : 1);
}

/** A kg/ha rate in a prescription's unit, through the server's kg_per_unit (kg/ha in 1
 * unit/ha): "150.0 l/ha". */
export function formatUnitRate(kgHa: number | null | undefined, kgPerUnit: number | null | undefined, unit: string): string {
  if (kgHa == null || !Number.isFinite(kgHa) || kgPerUnit == null || !(kgPerUnit > 0)) return '–';
  return `${amount(kgHa / kgPerUnit)} ${unit}`;
}

/** A total the server gave in a unit's own count or volume: "1,234,567 seeds", "150.3 l". */
export function formatUnitTotal(total: number | null | undefined, unit: string): string {
  if (total == null || !Number.isFinite(total)) return '–';
  return `${amount(total)} ${unit}`;
}

export function msToKmh(ms: number): number {
  return ms * 3.6;
}

export function kmhToMs(kmh: number): number {
  return kmh / 3.6;
}

/** Speed given in m/s, shown in km/h. */
export function formatSpeed(ms: number | null | undefined): string {
  if (ms == null || !Number.isFinite(ms)) return '–';
  return `${num(msToKmh(ms), 1)} km/h`;
}

export function formatDistance(m: number | null | undefined): string {
  if (m == null || !Number.isFinite(m)) return '–';
  if (Math.abs(m) < 1000) return `${num(m, 0)} m`;
  return `${num(m / 1000, 2)} km`;
}

/** Fraction (0..1) -> "42.0 %". */
export function formatPercent(frac: number | null | undefined, digits = 1): string {
  if (frac == null || !Number.isFinite(frac)) return '–';
  return `${num(frac * 100, digits)} %`;
}

export function formatMass(kg: number | null | undefined): string {
  if (kg == null || !Number.isFinite(kg)) return '–';
  if (Math.abs(kg) >= 10_000) return `${num(kg / 1000, 2)} t`;
  return `${num(kg, 1)} kg`;
}

/** Seconds -> "1 h 02 min", "3 min 05 s", "42 s". */
export function formatDuration(s: number | null | undefined): string {
  if (s == null || !Number.isFinite(s) || s < 0) return '–';
  const t = Math.round(s);
  const h = Math.floor(t / 3600);
  const m = Math.floor((t % 3600) / 60);
  const sec = t % 60;
  if (h > 0) return `${h} h ${String(m).padStart(2, '0')} min`;
  if (m > 0) return `${m} min ${String(sec).padStart(2, '0')} s`;
  return `${sec} s`;
}

/** Heading in degrees clockwise from north -> compass label. */
export function compass(deg: number | null | undefined): string {
  if (deg == null || !Number.isFinite(deg)) return '–';
  const dirs = ['N', 'NE', 'E', 'SE', 'S', 'SW', 'W', 'NW'];
  const d = ((deg % 360) + 360) % 360;
  return dirs[Math.round(d / 45) % 8];
}
