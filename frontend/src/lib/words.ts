import { RATE_MODELS } from './rateModels';

/**
 * Plain words for the API's names where a screen shows them: a model or heading rule the
 * server stores as an identifier, a request field a validation error points at. The
 * person reading the screen never sees snake_case.
 */

/** Prescription models in words: the server's rate models (generated/rate-models.json)
 * and the model name of an imported prescription. */
const MODELS: Record<string, string> = {
  ...Object.fromEntries(RATE_MODELS.map((m) => [m.name, m.short_label])),
  imported: 'Imported',
};

/** Plan heading rules, as the plan form names them. */
const HEADINGS: Record<string, string> = {
  longest_edge: 'Parallel to the longest edge',
  optimal: 'Optimal (fewest turns)',
  angle: 'Fixed heading',
};

/** Unit suffixes of request field names, as a reader writes them. */
const UNITS: [string, string][] = [
  ['_kg_ha', 'kg/ha'],
  ['_l_ha', 'l/ha'],
  ['_t_ha', 't/ha'],
  ['_mg_kg', 'mg/kg'],
  ['_km_h', 'km/h'],
  ['_m_s', 'm/s'],
  ['_kmh', 'km/h'],
  ['_pct', '%'],
  ['_deg', '°'],
  ['_mm', 'mm'],
  ['_m2', 'm²'],
  ['_ha', 'ha'],
  ['_m', 'm'],
  ['_s', 's'],
];

/** Abbreviations kept in capitals. */
const UPPER = new Set(['ndvi', 'nir', 'n', 'p', 'k', 'rpm', 'csv', 'gps', 'id']);

/**
 * "swath_width_m" -> "swath width (m)", "rate_curve.ndvi_lo" -> "rate curve, NDVI lo",
 * "plan_id" -> "plan". Anything without an underscore or dot is returned as it is.
 */
export function plainName(name: string): string {
  if (!/[_.]/.test(name)) return name;
  return name
    .split('.')
    .map((part) => {
      let unit = '';
      let base = part;
      if (base.endsWith('_id')) base = base.slice(0, -3);
      else
        for (const [suffix, u] of UNITS)
          if (base.endsWith(suffix) && base.length > suffix.length) {
            base = base.slice(0, -suffix.length);
            unit = ` (${u})`;
            break;
          }
      const words = base
        .split('_')
        .filter(Boolean)
        .map((w) => (UPPER.has(w) ? w.toUpperCase() : w));
      return words.join(' ') + unit;
    })
    .join(', ');
}

/** A prescription model in words ("nutrient_balance" -> "Nutrient balance (soil N)"). */
export function modelName(model: string | null | undefined): string {
  if (!model) return '–';
  return MODELS[model] ?? plainName(model);
}

/** A plan's heading rule in words ("longest_edge" -> "Parallel to the longest edge"). */
export function headingRuleName(rule: string | null | undefined): string {
  if (!rule) return '–';
  return HEADINGS[rule] ?? plainName(rule);
}
