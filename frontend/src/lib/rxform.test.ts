import { describe, expect, it } from 'vitest';
import { defaultFields, formatProduct, rxBody, withCrop, type Crop, type Product } from './rxform';

const crops: Crop[] = [
  { key: 'winter_rape', name: 'Winter oilseed rape', e_kg_per_100kg: 5.8, k_utilisation: 0.342, target_yield_t_ha: 2.5, source: 'seed 001' },
  { key: 'maize', name: 'Maize', e_kg_per_100kg: 2.57, k_utilisation: 0.342, target_yield_t_ha: 9, source: 'table' },
];
const products: Product[] = [
  { key: 'default:p', id: null, name: 'P only', n_pct: 0, p2o5_pct: 46, k2o_pct: 0, price_per_t: null, source: 'x' },
  { key: 'default:urea', id: null, name: 'Urea', n_pct: 46, p2o5_pct: 0, k2o_pct: 0, price_per_t: 400, source: 'x' },
];

describe('rx form fields -> body', () => {
  it('takes t/ha and sends kg/ha, with crop and product keys', () => {
    const f = defaultFields(crops, products);
    expect(f.productKey).toBe('default:urea'); // the first product with N
    const { body, errors } = rxBody('nutrient_balance', f);
    expect(errors).toEqual({});
    expect(body).toEqual({
      params: { target_yield_kg_ha: 2500, e_kg_per_100kg: 5.8, k_utilisation: 0.342 },
      crop: 'winter_rape',
      product_key: 'default:urea',
    });
  });
  it('switching crop replaces only the crop-dependent fields', () => {
    const f = { ...defaultFields(crops, products), clampMin: '100' };
    const g = withCrop(f, crops[1]);
    expect([g.targetYieldTHa, g.eKgPer100kg, g.clampMin, g.productKey]).toEqual(['9', '2.57', '100', 'default:urea']);
  });
  it('names the field of each error and sends nothing', () => {
    const f = { ...defaultFields(crops, products), targetYieldTHa: '', clampMin: '500', clampMax: '400' };
    const { body, errors } = rxBody('nutrient_balance', f);
    expect(body).toBeNull();
    expect(errors.targetYieldTHa).toMatch(/required/);
    expect(errors.clampMax).toMatch(/below the minimum/);
  });
  it('uniform and NDVI models', () => {
    const f = { ...defaultFields(crops, products), uniformRate: '250', clampMax: '300' };
    expect(rxBody('uniform', f).body).toEqual({ params: { rate_kg_ha: 250 }, product_key: 'default:urea', clamp_max_kg_ha: 300 });
    expect(rxBody('ndvi', { ...f, ndviHigh: '0.1' }).errors.ndviHigh).toMatch(/exceed/);
  });
  it('formats product mass in kg or t', () => {
    expect(formatProduct(720)).toBe('720.0 kg');
    expect(formatProduct(12_345)).toBe('12.345 t');
  });
});
