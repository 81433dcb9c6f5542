import { describe, expect, it } from 'vitest';
import { RATE_MODELS, ZONE_MODELS, paramDefault, rateModel } from './rateModels';

describe('rate models from the server registry', () => {
  it('lists every model with its label, and zones only those with a per-cell input', () => {
    expect(RATE_MODELS.map((m) => m.name)).toContain('uniform');
    expect(RATE_MODELS.every((m) => m.label !== '')).toBe(true);
    expect(ZONE_MODELS.every((m) => m.input != null)).toBe(true);
    expect(ZONE_MODELS.map((m) => m.name)).not.toContain('uniform');
  });

  it('gives a parameter default as the form shows it', () => {
    expect(paramDefault('ndvi', 'ndvi_low')).toBe('0.24');
    expect(paramDefault('uniform', 'rate_kg_ha')).toBe('');
    expect(rateModel('magic')).toBeUndefined();
  });
});
