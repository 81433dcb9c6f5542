/**
 * The prescription form as typed fields with units (no JSON box): crop, target yield in
 * t/ha, product from the catalogue, model parameters with where each default comes from,
 * the agronomist's min / max clamp. Pure: turns the fields into a PrescriptionIn body.
 */
import type { Schemas } from '../api/client';
import { paramDefault, rateModel, type RateModelInfo, type RateModelParam } from './rateModels';
import { BASE_UNIT, LOT_VALUES, RATE_UNITS, rateUnit, type LotValueInfo } from './rateUnits';
import { formatRate, formatUnitRate, formatUnitTotal } from './units';
import { plainName } from './words';

export type Crop = Schemas['CropOut'];
export type Product = Schemas['ProductOut'];
/** A rate model's name (generated/rate-models.json). */
export type RxModel = string;
/** The models RxModelFields has hand-written fields for; every other model gets one
 * numeric input per parameter the registry declares (genericParams). */
export const HAND_WRITTEN_MODELS: readonly string[] = ['nutrient_balance', 'uniform', 'ndvi'];

/** Every field is the text the user typed ('' = not given). */
export interface RxFields {
  crop: string;
  targetYieldTHa: string;
  productKey: string;
  eKgPer100kg: string;
  kUtilisation: string;
  dIntercept: string;
  dSlope: string;
  uniformRate: string;
  ndviLow: string;
  rateAtLow: string;
  ndviHigh: string;
  rateAtHigh: string;
  clampMin: string;
  clampMax: string;
  /** The unit the prescription goes to machines in (generated/rate-units.json). */
  rateUnit: string;
  /** Product lot values by key (density_kg_l, ...): from the product when it states them. */
  lot: Record<string, string>;
  /** A unit that sows a seed lot: the seed's name (variety, lot), sent as the product. */
  seedName?: string;
  /** A generic model's parameters by model, then name; a missing one shows its default. */
  modelParams: Record<string, Record<string, string>>;
}

/** Seed 000 NDVI curve (0.24 -> 375 kg/ha, 0.65 -> 180 kg/ha, docs/science.md), as the
 * server's ndvi model declares it (generated/rate-models.json). */
export const NDVI_DEFAULTS = {
  ndviLow: paramDefault('ndvi', 'ndvi_low'),
  rateAtLow: paramDefault('ndvi', 'rate_at_low_kg_ha'),
  ndviHigh: paramDefault('ndvi', 'ndvi_high'),
  rateAtHigh: paramDefault('ndvi', 'rate_at_high_kg_ha'),
};
export const NDVI_SOURCE = rateModel('ndvi')?.paper ?? '';

/** What the form starts from on a field (GET /fields/{id}/rx-defaults). */
export type FormDefaults = Schemas['FormDefaultsOut'];

/** A crop default's value as the form shows it ('' when the crop has no such value). */
export function cropValue(crop: Crop | undefined, name: string): string {
  const v = crop?.values?.[name];
  return v ? String(v.value) : '';
}

/**
 * Fields filled from the field's crop (else the first crop), the field's last product and
 * yield goal (else the first product with N and the crop's yield); each value's source is
 * shown beside it.
 */
export function defaultFields(crops: Crop[], products: Product[], from?: Partial<FormDefaults> | null): RxFields {
  const crop = crops.find((c) => c.key === from?.crop) ?? crops[0];
  const product = products.find((p) => p.key === from?.product_key) ?? products.find((p) => p.n_pct > 0);
  const base = crop ? withCrop({} as RxFields, crop) : ({} as RxFields);
  return {
    ...base,
    crop: crop?.key ?? '',
    targetYieldTHa: from?.target_yield_t_ha != null ? String(from.target_yield_t_ha) : crop ? String(crop.target_yield_t_ha) : '',
    productKey: product?.key ?? '',
    eKgPer100kg: crop ? String(crop.e_kg_per_100kg) : '',
    kUtilisation: crop ? String(crop.k_utilisation) : '',
    uniformRate: '300',
    ...NDVI_DEFAULTS,
    clampMin: '',
    clampMax: '',
    rateUnit: BASE_UNIT,
    lot: productLot(product, {}),
    modelParams: {},
  };
}

/** A lot value the product states ('' when it does not). */
export function productLotValue(p: Product | undefined, key: string): string {
  const v = (p as Record<string, unknown> | undefined)?.[key];
  return typeof v === 'number' && Number.isFinite(v) ? String(v) : '';
}

/** Lot values filled in from the product where it states them; the others kept. */
function productLot(p: Product | undefined, lot: Record<string, string>): Record<string, string> {
  const out = { ...lot };
  for (const v of LOT_VALUES) {
    const x = productLotValue(p, v.key);
    if (x) out[v.key] = x;
  }
  return out;
}

/**
 * Another product: its lot values replace the old product's (a value the user typed
 * stays); the unit stays, and a lot value the new product does not state is typed in.
 */
export function withProduct(f: RxFields, products: Product[], key: string): RxFields {
  const old = products.find((x) => x.key === f.productKey);
  const p = products.find((x) => x.key === key);
  const lot: Record<string, string> = {};
  for (const [k, v] of Object.entries(f.lot ?? {})) if (!old || v !== productLotValue(old, k)) lot[k] = v;
  return { ...f, productKey: key, lot: productLot(p, lot) };
}

/** The product's lot values in the fields that are still empty (a product just added to the
 * catalogue, found only once the catalogue is read again); the same fields when none is. */
export function withProductLot(f: RxFields, products: Product[]): RxFields {
  const p = products.find((x) => x.key === f.productKey);
  const missing = LOT_VALUES.filter((v) => !f.lot?.[v.key] && productLotValue(p, v.key));
  if (!missing.length) return f;
  const lot = { ...f.lot };
  for (const v of missing) lot[v.key] = productLotValue(p, v.key);
  return { ...f, lot };
}

/** A generic model's parameter as its input shows it: what was typed, else its default. */
export function paramText(f: RxFields, model: string, p: RateModelParam): string {
  return f.modelParams?.[model]?.[p.name] ?? (p.default == null ? '' : String(p.default));
}

/** A parameter's unit in the form: a rate of a model that prescribes in the prescription's
 * unit is in that unit, not kg/ha. */
export function paramUnit(m: RateModelInfo, p: RateModelParam, unit: string): string {
  return m.rates_in_unit && RATE_UNITS.some((u) => u.name === p.unit) ? unit : p.unit;
}

/** "seeds_at_low" -> "Seeds at low" (the unit is shown beside the input). */
export function paramLabel(name: string): string {
  const words = plainName(name).replace(/ \([^)]*\)$/, '');
  return words.charAt(0).toUpperCase() + words.slice(1);
}

/** The parameters of a model without hand-written fields (none for the others). */
export function genericParams(model: string): RateModelParam[] {
  return HAND_WRITTEN_MODELS.includes(model) ? [] : (rateModel(model)?.params ?? []);
}

/** The lot values the unit converts through. */
export function unitLot(unit: string): LotValueInfo[] {
  return rateUnit(unit)?.lot ?? [];
}

/** A new crop's defaults replace the crop-dependent fields only (yield, e, k, eq. 20's a and b). */
export function withCrop(f: RxFields, crop: Crop): RxFields {
  return {
    ...f,
    crop: crop.key,
    targetYieldTHa: String(crop.target_yield_t_ha),
    eKgPer100kg: String(crop.e_kg_per_100kg),
    kUtilisation: String(crop.k_utilisation),
    dIntercept: cropValue(crop, 'd_intercept_pct'),
    dSlope: cropValue(crop, 'd_slope_pct_mg_kg'),
  };
}

/** Errors by field: an RxFields key, `lot.${key}` or `param.${name}`. */
export type FieldErrors = Partial<Record<keyof RxFields | `lot.${string}` | `param.${string}`, string>>;

function num(v: string): number | null {
  if (v.trim() === '') return null;
  const x = Number(v);
  return Number.isFinite(x) ? x : NaN;
}

export interface RxBody {
  params: Record<string, number>;
  crop?: string;
  product_key?: string;
  /** the product's name where no catalogue product is meant (a seed lot) */
  product?: string;
  clamp_min_kg_ha?: number;
  clamp_max_kg_ha?: number;
  /** the registry's unit names (generated/rate-units.json, the same as the schema's) */
  rate_unit?: Schemas['PrescriptionIn']['rate_unit'];
  lot?: Record<string, number>;
}

/** The request body parts from the fields, or the errors per field (nothing is sent then). */
export function rxBody(model: RxModel, f: RxFields): { body: RxBody | null; errors: FieldErrors } {
  const errors: FieldErrors = {};
  const check = (k: keyof FieldErrors, text: string, what: string, ok: (x: number) => boolean): number => {
    const x = num(text ?? '');
    if (x == null) errors[k] = `${what} is required`;
    else if (Number.isNaN(x) || !ok(x)) errors[k] = `${what}: ${text} is out of range`;
    return x ?? NaN;
  };
  const need = (k: keyof RxFields, what: string, ok: (x: number) => boolean): number => check(k, f[k] as string, what, ok);
  const params: Record<string, number> = {};
  if (model === 'nutrient_balance') {
    params.target_yield_kg_ha = need('targetYieldTHa', 'Target yield (t/ha)', (x) => x > 0) * 1000;
    params.e_kg_per_100kg = need('eKgPer100kg', 'N uptake (kg N / 100 kg)', (x) => x > 0);
    params.k_utilisation = need('kUtilisation', 'N utilisation', (x) => x > 0 && x <= 1);
    if (f.dIntercept?.trim()) params.d_intercept_pct = need('dIntercept', 'Soil correction a (%)', (x) => Number.isFinite(x));
    if (f.dSlope?.trim()) params.d_slope_pct_mg_kg = need('dSlope', 'Soil correction b (% mg/kg)', (x) => x >= 0);
    if (!f.productKey) errors.productKey = 'choose a product (its N % gives the rate)';
  } else if (model === 'uniform') {
    params.rate_kg_ha = need('uniformRate', 'Rate (kg/ha)', (x) => x >= 0);
  } else if (model !== 'ndvi') {
    for (const p of genericParams(model)) {
      const text = paramText(f, model, p);
      // a parameter without a default left empty: the server fills it in or names it
      if (p.default == null && !text.trim()) continue;
      params[p.name] = check(`param.${p.name}`, text, paramLabel(p.name), Number.isFinite);
    }
  } else {
    params.ndvi_low = need('ndviLow', 'NDVI low', (x) => x >= -1 && x <= 1);
    params.rate_at_low_kg_ha = need('rateAtLow', 'Rate at NDVI low', (x) => x >= 0);
    params.ndvi_high = need('ndviHigh', 'NDVI high', (x) => x >= -1 && x <= 1);
    params.rate_at_high_kg_ha = need('rateAtHigh', 'Rate at NDVI high', (x) => x >= 0);
    if (!errors.ndviHigh && !errors.ndviLow && params.ndvi_high <= params.ndvi_low)
      errors.ndviHigh = 'NDVI high must exceed NDVI low';
  }
  const lo = num(f.clampMin);
  const hi = num(f.clampMax);
  if (lo != null && (Number.isNaN(lo) || lo < 0)) errors.clampMin = 'Minimum rate must be >= 0 kg/ha';
  if (hi != null && (Number.isNaN(hi) || hi < 0)) errors.clampMax = 'Maximum rate must be >= 0 kg/ha';
  if (lo != null && hi != null && lo > hi) errors.clampMax = `Maximum ${hi} is below the minimum ${lo} kg/ha`;
  const lot: Record<string, number> = {};
  for (const v of unitLot(f.rateUnit)) {
    const what = `${v.label[0].toUpperCase()}${v.label.slice(1)} (${v.unit})`;
    lot[v.key] = check(`lot.${v.key}`, f.lot?.[v.key] ?? '', what, (x) => x >= v.min && x <= v.max);
    if (errors[`lot.${v.key}`]?.endsWith('out of range')) errors[`lot.${v.key}`] += ` ${v.min}-${v.max} ${v.unit}`;
  }
  if (Object.keys(errors).length) return { body: null, errors };
  const body: RxBody = { params };
  if (model === 'nutrient_balance' && f.crop) body.crop = f.crop;
  // a seed lot is not a catalogue fertiliser: its name and lot values go with the request
  if (rateUnit(f.rateUnit)?.seed_lot) {
    if (f.seedName?.trim()) body.product = f.seedName.trim();
  } else if (f.productKey) body.product_key = f.productKey;
  if (lo != null) body.clamp_min_kg_ha = lo;
  if (hi != null) body.clamp_max_kg_ha = hi;
  if (f.rateUnit && f.rateUnit !== BASE_UNIT) body.rate_unit = f.rateUnit as RxBody['rate_unit'];
  if (Object.keys(lot).length) body.lot = lot;
  return { body, errors };
}

/** How a prescription goes to machines: "kg/ha", or "l/ha through 1.28 kg/l · mean 150.0 l/ha"
 * (the server works its rates out in kg/ha and says how many kg/ha one unit is, kg_per_unit;
 * job packages and ISOXML carry the unit). */
export function rateUnitText(
  rx: { rate_unit?: string; lot?: Record<string, number> | null; kg_per_unit?: number | null } | undefined,
  meanKgHa?: number | null,
): string {
  if (!rx) return '–';
  const unit = rx.rate_unit || BASE_UNIT;
  if (unit === BASE_UNIT) return unit;
  const through = unitLot(unit)
    .filter((v) => rx.lot?.[v.key] != null)
    .map((v) => `${rx.lot?.[v.key]} ${v.unit}`);
  if (rx.kg_per_unit == null) return `${unit} · the product lot does not say how much one ${unit} is`;
  return `${unit}${through.length ? ` through ${through.join(', ')}` : ''} · mean ${formatUnitRate(meanKgHa, rx.kg_per_unit, unit)}`;
}

/** A job report's totals in its prescription's unit ("planned 1,234,567 seeds · applied
 * 1,100,000 seeds"), as the server counted them; null for the base unit (the report's kg say
 * it) or when the product lot does not say how much one unit is. */
export function unitTotalsText(
  u: { rate_unit: string; kg_per_unit: number | null; total_unit: string; planned_total: number | null; applied_total: number | null } | null | undefined,
): string | null {
  if (!u || u.rate_unit === BASE_UNIT || u.kg_per_unit == null) return null;
  return `planned ${formatUnitTotal(u.planned_total, u.total_unit)} · applied ${formatUnitTotal(u.applied_total, u.total_unit)}`;
}

/** "46 % N, 0 % P2O5, 0 % K2O · 420 /t" */
export function productText(p: Product): string {
  const npk = `${p.n_pct} % N, ${p.p2o5_pct} % P2O5, ${p.k2o_pct} % K2O`;
  const liquid = p.density_kg_l ? ` · liquid, ${p.density_kg_l} kg/l` : '';
  return (p.price_per_t == null ? `${npk} · no price` : `${npk} · ${p.price_per_t} /t`) + liquid;
}

/** kg below 10 t, else t (3 decimals). */
export function formatProduct(kg: number | null | undefined): string {
  if (kg == null || !Number.isFinite(kg)) return '–';
  return Math.abs(kg) >= 10_000 ? `${(kg / 1000).toFixed(3)} t` : `${kg.toFixed(1)} kg`;
}

/** [lo, hi] of what a machine meters; rates outside it (0 = off is always fine). */
export function outsideMeter(s: { rate_min_kg_ha?: number | null; rate_max_kg_ha?: number | null }, lo: number, hi: number): string | null {
  const min = s.rate_min_kg_ha;
  const max = s.rate_max_kg_ha;
  const parts: string[] = [];
  if (min != null && min > 0 && min < lo) parts.push(`lowest rate ${formatRate(min)} is below ${formatRate(lo)}`);
  if (max != null && max > hi) parts.push(`highest rate ${formatRate(max)} is above ${formatRate(hi)}`);
  return parts.length ? parts.join('; ') : null;
}

/**
 * "683.2 kg/ha · 184.5 kg N/ha": a product rate with the kg of each nutrient per ha it
 * carries (the product's analysis; nutrient_balance without a product: its N fraction).
 */
export function nutrientRateText(rateKgHa: number | null | undefined, fractions: Record<string, number> | null | undefined): string {
  if (rateKgHa == null || !Number.isFinite(rateKgHa)) return '–';
  const parts = Object.entries(fractions ?? {})
    .filter(([, x]) => x > 0)
    .map(([n, x]) => `${(rateKgHa * x).toFixed(1)} kg ${n}/ha`);
  return [`${rateKgHa.toFixed(1)} kg/ha`, ...parts].join(' · ');
}

/** The nutrient fractions a version's summary was checked with (or its product's analysis). */
export function summaryFractions(s: unknown): Record<string, number> {
  const o = (s ?? {}) as { plausibility?: { fractions?: Record<string, number> }; product?: { n_pct?: number; p2o5_pct?: number; k2o_pct?: number } | null };
  if (o.plausibility?.fractions && Object.keys(o.plausibility.fractions).length) return o.plausibility.fractions;
  const p = o.product;
  return p ? { N: (p.n_pct ?? 0) / 100, P2O5: (p.p2o5_pct ?? 0) / 100, K2O: (p.k2o_pct ?? 0) / 100 } : {};
}

/** The prescription's unit when its rates are also shown in it (not the base unit, and the
 * server said how many kg/ha one unit is); null: kg/ha only. */
export interface ShownUnit {
  name: string;
  kgPerUnit: number;
}

export function shownUnit(rx: { rate_unit?: string | null; kg_per_unit?: number | null } | null | undefined): ShownUnit | null {
  if (!rx?.rate_unit || rx.rate_unit === BASE_UNIT || !(rx.kg_per_unit && rx.kg_per_unit > 0)) return null;
  return { name: rx.rate_unit, kgPerUnit: rx.kg_per_unit };
}

/** " · 72,000 seeds/ha": a kg/ha figure in the prescription's unit ('' in kg/ha only). */
export function alsoInUnit(kgHa: number | null | undefined, u: ShownUnit | null): string {
  return u && kgHa != null && Number.isFinite(kgHa) ? ` · ${formatUnitRate(kgHa, u.kgPerUnit, u.name)}` : '';
}
