import type { ReactNode } from 'react';

/** One map view of a kind's report: the button, the per-cell column it colours by. */
export interface KindView {
  key: string;
  label: string;
  column: string;
  decimals: number;
}

/** A row of the report's key-value list: label, value, test id. */
export type KindRow = [string, string, string?];

/**
 * What the screens show of a kind beyond what GET /jobs/kinds says (its form is built from
 * that response): a note under the form, the report's figures, table and map views. One
 * module per kind in src/kinds/, named after it; a kind with none gets the generic screens.
 */
export interface KindUi {
  name: string;
  formNote?: (values: Record<string, string>) => ReactNode;
  views?: KindView[];
  reportRows?: (r: Record<string, unknown>, settings: Record<string, unknown>) => KindRow[];
  reportTable?: (r: Record<string, unknown>) => ReactNode;
}

export const f1 = (v: unknown, d = 1) => (typeof v === 'number' && Number.isFinite(v) ? v.toFixed(d) : '–');
