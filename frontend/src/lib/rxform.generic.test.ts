// A rate unit and a rate model the form has no hand-written code for: both come from the
// generated registries, so the form's inputs, its checks and its texts follow them.
import { describe, expect, it, vi } from 'vitest';

vi.mock('../api/generated/rate-units.json', async (importOriginal) => {
  const real = (await importOriginal()) as { default: { rate_units: unknown[] } };
  const unit = {
    name: 'grains/ha',
    label: 'grains/ha (count)',
    quantity: 'count',
    lot: [
      { key: 'tgw_g', label: 'thousand-grain weight', unit: 'g', min: 1, max: 100 },
      { key: 'viable_pct', label: 'viability', unit: '%', min: 10, max: 100 },
    ],
    seed_lot: true,
    ddi_setpoint: 0,
    ddi_actual: 0,
  };
  return { default: { rate_units: [...real.default.rate_units, unit] } };
});
vi.mock('../api/generated/rate-models.json', async (importOriginal) => {
  const real = (await importOriginal()) as { default: { rate_models: unknown[] } };
  const model = {
    name: 'grain_curve',
    aliases: [],
    label: 'Grain curve',
    short_label: 'Grain curve',
    zone_label: 'Grain curve',
    paper: 'test',
    input: 'ndvi',
    crop_defaults: false,
    rates_in_unit: true,
    params: [
      { name: 'ndvi_at_low', unit: '', default: 0.3, source: 'the test' },
      { name: 'grains_at_low', unit: 'kg/ha', default: 500000, source: 'the test' },
      { name: 'cap_kg_ha', unit: 'kg/ha', default: null, source: 'the crop' },
    ],
  };
  return { default: { rate_models: [...real.default.rate_models, model] } };
});

const { defaultFields, genericParams, paramLabel, paramText, paramUnit, rateUnitText, rxBody } = await import('./rxform');
const { rateModel } = await import('./rateModels');

describe('a rate unit from the registry', () => {
  const f = { ...defaultFields([], []), rateUnit: 'grains/ha' };

  it('needs every lot value of the unit, each in its range', () => {
    const { body, errors } = rxBody('uniform', f);
    expect(body).toBeNull();
    expect(errors).toEqual({ 'lot.tgw_g': 'Thousand-grain weight (g) is required', 'lot.viable_pct': 'Viability (%) is required' });
    expect(rxBody('uniform', { ...f, lot: { tgw_g: '48', viable_pct: '120' } }).errors).toEqual({
      'lot.viable_pct': 'Viability (%): 120 is out of range 10-100 %',
    });
  });

  it('names a seed lot instead of sending a catalogue fertiliser', () => {
    const lot = { tgw_g: '48', viable_pct: '95' };
    const body = rxBody('uniform', { ...f, productKey: 'default:urea', seedName: ' Wheat Bussard ', lot }).body;
    expect(body?.product_key).toBeUndefined();
    expect(body?.product).toBe('Wheat Bussard');
    expect(rxBody('uniform', { ...f, productKey: 'default:urea', rateUnit: 'kg/ha', lot }).body?.product_key).toBe('default:urea');
  });

  it('sends the unit and its lot', () => {
    const body = rxBody('uniform', { ...f, lot: { tgw_g: '48', viable_pct: '95', density_kg_l: '1.2' } }).body;
    expect(body?.rate_unit).toBe('grains/ha');
    // only the chosen unit's values
    expect(body?.lot).toEqual({ tgw_g: 48, viable_pct: 95 });
  });

  it('says the lot and the mean rate in the unit, through the server kg_per_unit', () => {
    const rx = { rate_unit: 'grains/ha', lot: { tgw_g: 48, viable_pct: 95, density_kg_l: 1.2 }, kg_per_unit: 0.00004 };
    expect(rateUnitText(rx, 26)).toBe('grains/ha through 48 g, 95 % · mean 650,000 grains/ha');
  });
});

describe('a rate model without hand-written fields', () => {
  const f = { ...defaultFields([], []), rateUnit: 'grains/ha', lot: { tgw_g: '48', viable_pct: '95' } };
  const m = rateModel('grain_curve')!;

  it('gets one input per parameter, labelled and in the prescription unit for its rates', () => {
    expect(genericParams('grain_curve').map((p) => p.name)).toEqual(['ndvi_at_low', 'grains_at_low', 'cap_kg_ha']);
    expect(genericParams('uniform')).toEqual([]);
    expect(m.params.map((p) => paramLabel(p.name))).toEqual(['NDVI at low', 'Grains at low', 'Cap']);
    expect(m.params.map((p) => paramUnit(m, p, 'grains/ha'))).toEqual(['', 'grains/ha', 'grains/ha']);
    expect(m.params.map((p) => paramText(f, 'grain_curve', p))).toEqual(['0.3', '500000', '']);
  });

  it('sends its defaults and the values typed; one without a default may stay empty', () => {
    expect(rxBody('grain_curve', f).body?.params).toEqual({ ndvi_at_low: 0.3, grains_at_low: 500000 });
    const typed = { ...f, modelParams: { grain_curve: { grains_at_low: '420000', cap_kg_ha: '30' } } };
    expect(rxBody('grain_curve', typed).body?.params).toEqual({ ndvi_at_low: 0.3, grains_at_low: 420000, cap_kg_ha: 30 });
  });

  it('names a bad parameter and sends nothing', () => {
    const bad = { ...f, modelParams: { grain_curve: { ndvi_at_low: '', grains_at_low: 'many' } } };
    expect(rxBody('grain_curve', bad)).toEqual({
      body: null,
      errors: { 'param.ndvi_at_low': 'NDVI at low is required', 'param.grains_at_low': 'Grains at low: many is out of range' },
    });
  });
});
