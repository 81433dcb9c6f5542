/**
 * The server's defaults of its request models (`PlanIn.headland_passes`,
 * `PrescriptionIn.interpolation`, ...), generated from the OpenAPI document by
 * `scripts/gen-api.sh` into `generated/defaults.json`. Forms start from these, never from a
 * copy of their own: a copy drifted once (plan form 1 headland pass vs the API's 0,
 * interpolation `idw` vs `cell_mean`). `tests/system/test_contract.py` fails when the file is
 * stale; `defaults.test.ts` when a form keeps its own copy.
 */
import generated from './generated/defaults.json';
import type { Schemas } from './client';

type Defaults = {
  [M in keyof Schemas]?: Partial<Schemas[M]>;
};

export const DEFAULTS = generated as Defaults;

/** The server's default of `model.field` (throws when the server has none: a form needs one). */
export function serverDefault<M extends keyof Schemas, K extends keyof Schemas[M] & string>(
  model: M,
  field: K,
): NonNullable<Schemas[M][K]> {
  const v = (DEFAULTS[model] as Record<string, unknown> | undefined)?.[field];
  if (v === undefined || v === null) throw new Error(`the API declares no default for ${model}.${field}`);
  return v as NonNullable<Schemas[M][K]>;
}
