/**
 * The prescription form as typed fields with units (no JSON box): crop, target yield in
 * t/ha, product from the catalogue, model parameters with where each default comes from,
 * the agronomist's min / max clamp. Pure: turns the fields into a PrescriptionIn body.
 */
import type { Schemas } from '../api/client';
import { paramDefault, rateModel } from './rateModels';
import { formatRate, formatVolumeRate } from './units';

export type Crop = Schemas['CropOut'];
export type Product = Schemas['ProductOut'];
export type RxModel = 'nutrient_balance' | 'uniform' | 'ndvi';

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
  /** 'l/ha': a liquid (a product with a density) goes to machines by volume. */
  rateUnit: string;
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
    rateUnit: 'kg/ha',
  };
}

/** Another product: a rate unit of l/ha stays only while the product has a density. */
export function withProduct(f: RxFields, products: Product[], key: string): RxFields {
  const p = products.find((x) => x.key === key);
  return { ...f, productKey: key, rateUnit: p?.density_kg_l ? f.rateUnit : 'kg/ha' };
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

export type FieldErrors = Partial<Record<keyof RxFields, string>>;

function num(v: string): number | null {
  if (v.trim() === '') return null;
  const x = Number(v);
  return Number.isFinite(x) ? x : NaN;
}

export interface RxBody {
  params: Record<string, number>;
  crop?: string;
  product_key?: string;
  clamp_min_kg_ha?: number;
  clamp_max_kg_ha?: number;
  rate_unit?: 'l/ha';
}

/** The request body parts from the fields, or the errors per field (nothing is sent then). */
export function rxBody(model: RxModel, f: RxFields): { body: RxBody | null; errors: FieldErrors } {
  const errors: FieldErrors = {};
  const need = (k: keyof RxFields, what: string, ok: (x: number) => boolean): number => {
    const x = num(f[k]);
    if (x == null) errors[k] = `${what} is required`;
    else if (Number.isNaN(x) || !ok(x)) errors[k] = `${what}: ${f[k]} is out of range`;
    return x ?? NaN;
  };
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
  if (Object.keys(errors).length) return { body: null, errors };
  const body: RxBody = { params };
  if (model === 'nutrient_balance' && f.crop) body.crop = f.crop;
  if (f.productKey) body.product_key = f.productKey;
  if (lo != null) body.clamp_min_kg_ha = lo;
  if (hi != null) body.clamp_max_kg_ha = hi;
  if (f.rateUnit === 'l/ha') body.rate_unit = 'l/ha';
  return { body, errors };
}

/** How a prescription goes to machines: "kg/ha", or "l/ha through 1.28 kg/l · mean 150.0 l/ha"
 * (the server works its rates out in kg/ha; job packages and ISOXML carry l/ha). */
export function rateUnitText(rx: { rate_unit?: string; density_kg_l?: number | null } | undefined, meanKgHa?: number | null): string {
  if (!rx) return '–';
  if (rx.rate_unit !== 'l/ha' || !rx.density_kg_l) return 'kg/ha';
  return `l/ha through ${rx.density_kg_l} kg/l · mean ${formatVolumeRate(meanKgHa, rx.density_kg_l)}`;
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
