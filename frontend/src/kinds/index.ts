/**
 * The kinds' screen parts, found by file: every src/kinds/<kind>.tsx exports `ui`. Adding a
 * kind's module here is all the UI needs; its form comes from GET /jobs/kinds.
 */
import type { KindUi } from './types';

const modules = import.meta.glob<{ ui: KindUi }>('./*.tsx', { eager: true });
const BY_NAME: Record<string, KindUi> = Object.fromEntries(Object.values(modules).map((m) => [m.ui.name, m.ui]));

/** The screen parts of a kind (none: the generic form and report). */
export function kindUi(name: string | null | undefined): KindUi {
  return (name && BY_NAME[name]) || { name: name ?? '' };
}

/** The value a kind's map colours a cell by in one of its views. */
export function cellValue(ui: KindUi, view: string, cell: Record<string, unknown>): number | null {
  const column = ui.views?.find((v) => v.key === view)?.column;
  const v = column ? cell[column] : undefined;
  return typeof v === 'number' && Number.isFinite(v) ? v : null;
}
