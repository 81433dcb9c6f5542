// The machine's meterable range beside the prescription's rates (issue 15 scope 4).
// (The screens' state and map-layer rules are checked for every screen and component in
// screens.test.ts.)
import { describe, expect, it } from 'vitest';
import { defaultFields, outsideMeter, rateUnitText, rxBody, withProduct, type Product } from '../lib/rxform';

describe('outsideMeter', () => {
  it('names the rates a machine cannot meter; 0 (off) is fine', () => {
    expect(outsideMeter({ rate_min_kg_ha: 0, rate_max_kg_ha: 700 }, 583.6, 882.1)).toBeNull();
    expect(outsideMeter({ rate_min_kg_ha: 500, rate_max_kg_ha: 900 }, 583.6, 882.1)).toBe(
      'lowest rate 500.0 kg/ha is below 583.6 kg/ha; highest rate 900.0 kg/ha is above 882.1 kg/ha',
    );
  });
});

describe('liquid products in l/ha', () => {
  const prod = (key: string, density: number | null): Product =>
    ({ key, name: key, n_pct: 28, p2o5_pct: 0, k2o_pct: 0, price_per_t: null, density_kg_l: density, source: 's' }) as Product;
  const products = [prod('uan', 1.28), prod('urea', null)];

  it('sends rate_unit l/ha only while the product has a density', () => {
    const f = { ...withProduct(defaultFields([], products), products, 'uan'), rateUnit: 'l/ha' };
    expect(rxBody('uniform', f).body?.rate_unit).toBe('l/ha');
    const solid = withProduct(f, products, 'urea');
    expect(solid.rateUnit).toBe('kg/ha');
    expect(rxBody('uniform', solid).body?.rate_unit).toBeUndefined();
  });

  it('shows how the prescription goes to machines', () => {
    expect(rateUnitText({ rate_unit: 'l/ha', density_kg_l: 1.28 }, 192)).toBe('l/ha through 1.28 kg/l · mean 150.0 l/ha');
    expect(rateUnitText({ rate_unit: 'kg/ha', density_kg_l: 1.28 }, 192)).toBe('kg/ha');
    expect(rateUnitText(undefined, 192)).toBe('–');
  });
});
