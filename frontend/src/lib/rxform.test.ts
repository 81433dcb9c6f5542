// The machine's meterable range beside the prescription's rates.
// (The screens' state and map-layer rules are checked for every screen and component in
// screens.test.ts.)
import { describe, expect, it } from 'vitest';
import { defaultFields, nutrientRateText, outsideMeter, rateUnitText, rxBody, unitTotalsText, withProduct, withProductLot, type Crop, type Product } from '../lib/rxform';

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
  const products = [prod('uan', 1.28), prod('urea', null), prod('uan32', 1.32), prod('can', null)];

  it("sends rate_unit l/ha with the product's density as the lot", () => {
    const f = { ...withProduct(defaultFields([], products), products, 'uan'), rateUnit: 'l/ha' };
    expect(f.lot.density_kg_l).toBe('1.28');
    expect(rxBody('uniform', f).body).toMatchObject({ rate_unit: 'l/ha', lot: { density_kg_l: 1.28 } });
    // another liquid: its density replaces the old product's
    expect(withProduct(f, products, 'uan32').lot.density_kg_l).toBe('1.32');
    // a solid: the unit stays, the density is typed in (nothing is sent until it is)
    const solid = withProduct(f, products, 'urea');
    expect([solid.rateUnit, solid.lot.density_kg_l]).toEqual(['l/ha', undefined]);
    expect(rxBody('uniform', solid)).toEqual({ body: null, errors: { 'lot.density_kg_l': 'Density (kg/l) is required' } });
    expect(rxBody('uniform', { ...solid, lot: { density_kg_l: '1.1' } }).body?.lot).toEqual({ density_kg_l: 1.1 });
    // a value the user typed stays for a product that does not state it, one that does wins
    expect(withProduct({ ...solid, lot: { density_kg_l: '1.1' } }, products, 'can').lot.density_kg_l).toBe('1.1');
    expect(withProduct({ ...solid, lot: { density_kg_l: '1.1' } }, products, 'uan').lot.density_kg_l).toBe('1.28');
  });

  it('checks a lot value against its range and sends nothing when it is wrong', () => {
    const f = { ...defaultFields([], products), rateUnit: 'l/ha', lot: { density_kg_l: '40' } };
    const { body, errors } = rxBody('uniform', f);
    expect(body).toBeNull();
    expect(errors['lot.density_kg_l']).toBe('Density (kg/l): 40 is out of range 0.05-5 kg/l');
    expect(rxBody('uniform', { ...f, lot: { density_kg_l: 'x' } }).body).toBeNull();
  });

  it('sends neither unit nor lot in kg/ha', () => {
    const body = rxBody('uniform', withProduct(defaultFields([], products), products, 'uan')).body;
    expect(body?.rate_unit).toBeUndefined();
    expect(body?.lot).toBeUndefined();
  });

  it("fills a product's lot values in once the catalogue has the product", () => {
    const f = { ...defaultFields([], []), productKey: 'uan', rateUnit: 'l/ha' };
    expect(f.lot.density_kg_l).toBeUndefined();
    expect(withProductLot(f, products).lot.density_kg_l).toBe('1.28');
    const typed = { ...f, lot: { density_kg_l: '1.3' } };
    expect(withProductLot(typed, products)).toBe(typed);
  });

  it('shows how the prescription goes to machines', () => {
    expect(rateUnitText({ rate_unit: 'l/ha', lot: { density_kg_l: 1.28 }, kg_per_unit: 1.28 }, 192)).toBe('l/ha through 1.28 kg/l · mean 150.0 l/ha');
    expect(rateUnitText({ rate_unit: 'kg/ha', lot: { density_kg_l: 1.28 }, kg_per_unit: 1 }, 192)).toBe('kg/ha');
    expect(rateUnitText({ rate_unit: 'l/ha', lot: {}, kg_per_unit: null }, 192)).toBe('l/ha · the product lot does not say how much one l/ha is');
    expect(rateUnitText(undefined, 192)).toBe('–');
  });
});

describe('unitTotalsText', () => {
  it("gives a job's totals in the prescription's unit, only when it is not kg/ha and converts", () => {
    const u = { rate_unit: 'l/ha', kg_per_unit: 1.28, lot: { density_kg_l: 1.28 }, total_unit: 'l', planned_total: 1234.56, applied_total: 150.26 };
    expect(unitTotalsText(u)).toBe('planned 1,235 l · applied 150.3 l');
    expect(unitTotalsText({ ...u, applied_total: null })).toBe('planned 1,235 l · applied –');
    expect(unitTotalsText({ ...u, kg_per_unit: null })).toBeNull();
    expect(unitTotalsText({ ...u, rate_unit: 'kg/ha', total_unit: 'kg' })).toBeNull();
    expect(unitTotalsText(null)).toBeNull();
  });
});

const v = (value: number, source = 'src') => ({ value, unit: 'u', source });
const crop = (key: string, e: number, k: number, y: number, b: number): Crop => ({
  key,
  name: key,
  e_kg_per_100kg: e,
  k_utilisation: k,
  target_yield_t_ha: y,
  source: 'src',
  ceilings_kg_ha: { N: 200 },
  n_reference: null,
  values: { e_kg_per_100kg: v(e), k_utilisation: v(k), target_yield_t_ha: v(y), d_intercept_pct: v(5.57), d_slope_pct_mg_kg: v(b) },
});
const CROPS = [crop('winter_rape', 5.8, 0.342, 2.5, 3226.05), crop('winter_wheat', 3, 0.282, 8, 7728.33)];
const product = (key: string, n: number): Product => ({ key, id: null, name: key, n_pct: n, p2o5_pct: 0, k2o_pct: 0, price_per_t: null, source: 's' });
const PRODUCTS = [product('default:urea', 46), product('default:can', 27)];

describe('defaultFields', () => {
  it("starts from the field's crop, its last product and yield goal, not the first crop", () => {
    const f = defaultFields(CROPS, PRODUCTS, { crop: 'winter_wheat', product_key: 'default:can', target_yield_t_ha: 7.5 });
    expect([f.crop, f.productKey, f.targetYieldTHa, f.kUtilisation, f.dSlope]).toEqual(['winter_wheat', 'default:can', '7.5', '0.282', '7728.33']);
    const g = defaultFields(CROPS, PRODUCTS, null);
    expect([g.crop, g.productKey, g.targetYieldTHa]).toEqual(['winter_rape', 'default:urea', '2.5']);
    // eq. 20's a and b are sent with the other parameters
    expect(rxBody('nutrient_balance', f).body?.params).toMatchObject({ d_intercept_pct: 5.57, d_slope_pct_mg_kg: 7728.33, target_yield_kg_ha: 7500 });
  });
});

describe('nutrientRateText', () => {
  it('gives kg of each nutrient per ha beside kg of product per ha', () => {
    expect(nutrientRateText(700, { N: 0.27, P2O5: 0, K2O: 0 })).toBe('700.0 kg/ha · 189.0 kg N/ha');
    expect(nutrientRateText(200, { N: 0.15, P2O5: 0.15, K2O: 0.15 })).toBe('200.0 kg/ha · 30.0 kg N/ha · 30.0 kg P2O5/ha · 30.0 kg K2O/ha');
    expect(nutrientRateText(null, { N: 0.27 })).toBe('–');
  });
});

describe('rates also in the prescription unit', () => {
  it('shows a kg/ha figure in the unit only when the server gave kg per unit', async () => {
    const { alsoInUnit, shownUnit } = await import('./rxform');
    expect(shownUnit({ rate_unit: 'kg/ha', kg_per_unit: 1 })).toBeNull();
    expect(shownUnit({ rate_unit: 'l/ha', kg_per_unit: null })).toBeNull();
    const u = shownUnit({ rate_unit: 'l/ha', kg_per_unit: 1.28 });
    expect(alsoInUnit(192, u)).toBe(' · 150.0 l/ha');
    expect(alsoInUnit(null, u)).toBe('');
    expect(alsoInUnit(192, null)).toBe('');
  });
});
