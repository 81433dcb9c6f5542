/**
 * Job kinds in the forms. The server's registry is the one list (GET /jobs/kinds: each kind's
 * label, where its rates come from and its settings with unit, default and the default's
 * source); this module turns a kind's form values into the body sent. Each kind's own screen
 * parts (previews, report tables) are in src/kinds/.
 */
import type { Schemas } from '../api/client';

export type KindInfo = Schemas['KindInfo'];
/** One form input: dotted settings path, label, unit, the default and its source. */
export type SettingField = Schemas['SettingSpecOut'];

/** The kinds in the registry's order. */
export function kindList(kinds: Record<string, KindInfo> | undefined): KindInfo[] {
  return Object.values(kinds ?? {});
}

/** A kind's label for lists, or its name while the kinds are not known. */
export function kindLabel(kinds: Record<string, KindInfo> | undefined, name: string | null | undefined): string {
  return (name && kinds?.[name]?.label) || String(name ?? '');
}

/**
 * Partial settings from the form's text values: only the inputs the user changed from the
 * default are sent (the server fills in the rest and names any bad one).
 */
export function settingsBody(fields: SettingField[], values: Record<string, string>): Record<string, unknown> {
  const out: Record<string, unknown> = {};
  for (const f of fields) {
    const raw = values[f.path];
    if (raw == null || raw === '' || raw === String(f.default)) continue;
    const v: unknown = typeof f.default === 'number' ? Number(raw) : typeof f.default === 'boolean' ? raw === 'true' : raw;
    const parts = f.path.split('.');
    let obj = out;
    for (const p of parts.slice(0, -1)) obj = (obj[p] ??= {}) as Record<string, unknown>;
    obj[parts[parts.length - 1]] = v;
  }
  return out;
}

/** The kinds whose job takes a prescription in this rate unit (GET /jobs/kinds: rate_units). */
export function kindsTaking(kinds: Record<string, KindInfo> | undefined, unit: string): KindInfo[] {
  return kindList(kinds).filter((k) => k.rates_from === 'cells' && k.rate_units.includes(unit));
}

/** Why a kind's job cannot take the prescription (its unit), as the server would refuse it;
 * null when it can (or the kind's rates come from sensors). */
export function unitRefusal(kind: Pick<KindInfo, 'name' | 'rates_from' | 'rate_units'>, rxId: number | string, unit: string): string | null {
  if (kind.rates_from !== 'cells' || kind.rate_units.includes(unit)) return null;
  const taken = kind.rate_units.length ? kind.rate_units.join(' or ') : 'no unit';
  return `prescription ${rxId} is in ${unit}: a ${kind.name} job takes prescriptions in ${taken}`;
}

/** POST /jobs body for any kind: a prescription for a kind whose rates are the cells', a
 * plan and the changed settings for one whose rates come from sensors. */
export function jobBody(
  kind: Pick<KindInfo, 'name' | 'rates_from' | 'settings'>,
  ids: { prescriptionId?: string; version?: string; planId?: string; machineId: string },
  values: Record<string, string> = {},
): Schemas['JobIn'] {
  if (kind.rates_from === 'cells') {
    return {
      kind: kind.name as Schemas['JobIn']['kind'],
      prescription_id: Number(ids.prescriptionId),
      prescription_version: ids.version ? Number(ids.version) : undefined,
      machine_id: Number(ids.machineId),
    };
  }
  return { kind: kind.name as Schemas['JobIn']['kind'], plan_id: Number(ids.planId), machine_id: Number(ids.machineId), settings: settingsBody(kind.settings, values) };
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
