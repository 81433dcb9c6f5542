/**
 * The prescription form as typed fields with units (no JSON box): crop, target yield in
 * t/ha, product from the catalogue, model parameters with where each default comes from,
 * the agronomist's min / max clamp. Pure: turns the fields into a PrescriptionIn body.
 */
import type { Schemas } from '../api/client';
import { formatRate } from './units';

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
  uniformRate: string;
  ndviLow: string;
  rateAtLow: string;
  ndviHigh: string;
  rateAtHigh: string;
  clampMin: string;
  clampMax: string;
}

/** Seed 000 NDVI curve (0.24 -> 375 kg/ha, 0.65 -> 180 kg/ha, docs/science.md). */
export const NDVI_DEFAULTS = { ndviLow: '0.24', rateAtLow: '375', ndviHigh: '0.65', rateAtHigh: '180' };
export const NDVI_SOURCE = 'seed 000 NDVI curve';

/** Fields filled from a crop and the first product with N (each value's source is shown beside it). */
export function defaultFields(crops: Crop[], products: Product[], cropKey?: string): RxFields {
  const crop = crops.find((c) => c.key === cropKey) ?? crops[0];
  const product = products.find((p) => p.n_pct > 0);
  return {
    crop: crop?.key ?? '',
    targetYieldTHa: crop ? String(crop.target_yield_t_ha) : '',
    productKey: product?.key ?? '',
    eKgPer100kg: crop ? String(crop.e_kg_per_100kg) : '',
    kUtilisation: crop ? String(crop.k_utilisation) : '',
    uniformRate: '300',
    ...NDVI_DEFAULTS,
    clampMin: '',
    clampMax: '',
  };
}

/** A new crop's defaults replace the crop-dependent fields only (yield, e, k). */
export function withCrop(f: RxFields, crop: Crop): RxFields {
  return {
    ...f,
    crop: crop.key,
    targetYieldTHa: String(crop.target_yield_t_ha),
    eKgPer100kg: String(crop.e_kg_per_100kg),
    kUtilisation: String(crop.k_utilisation),
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
  return { body, errors };
}

/** "46 % N, 0 % P2O5, 0 % K2O · 420 /t" */
export function productText(p: Product): string {
  const npk = `${p.n_pct} % N, ${p.p2o5_pct} % P2O5, ${p.k2o_pct} % K2O`;
  return p.price_per_t == null ? `${npk} · no price` : `${npk} · ${p.price_per_t} /t`;
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
