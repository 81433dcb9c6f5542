import type { Schemas } from '../api/client';

/** The mapping the confirm route reads (JSON of the server's `SoilMappingIn`, which is a
 * form field's text and so not in the document); the preview answers it as `SoilMappingOut`. */
export type MappingIn = Schemas['SoilMappingOut'];

/** "Not read": the column feeds no quantity. */
export const NO_TARGET = '';

/**
 * `m` with column `name` read as `target` (or not read): a quantity is fed by one column and
 * a column feeds one quantity, so both earlier pairings go; units and CRS stay.
 */
export function remap(m: MappingIn, name: string, target: string): MappingIn {
  const columns = Object.fromEntries(
    Object.entries(m.columns).filter(([t, c]) => c !== name && t !== target),
  );
  if (target !== NO_TARGET) columns[target] = name;
  return { ...m, columns };
}
