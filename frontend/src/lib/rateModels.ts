import registry from '../api/generated/rate-models.json';

/**
 * The server's rate models (backend/fieldrx/agronomy/ratemodels, written to
 * generated/rate-models.json by scripts/gen-api.sh): the forms' menus and labels read them
 * here, so a new model on the server is a new menu entry without a hand-written list.
 */
export interface RateModelParam {
  name: string;
  unit: string;
  default: number | null;
  source: string;
}

export interface RateModelInfo {
  name: string;
  aliases: string[];
  label: string;
  short_label: string;
  zone_label: string;
  paper: string;
  /** the sample column the model reads per cell; null: one rate everywhere */
  input: string | null;
  crop_defaults: boolean;
  rates_in_unit: boolean;
  params: RateModelParam[];
}

export const RATE_MODELS: RateModelInfo[] = registry.rate_models;

/** The models a zone map can be built for: those that read a per-cell input. */
export const ZONE_MODELS: RateModelInfo[] = RATE_MODELS.filter((m) => m.input != null);

export function rateModel(name: string): RateModelInfo | undefined {
  return RATE_MODELS.find((m) => m.name === name);
}

/** A parameter's default as a form field shows it ('' when it has none). */
export function paramDefault(model: string, param: string): string {
  const d = rateModel(model)?.params.find((p) => p.name === param)?.default;
  return d == null ? '' : String(d);
}
