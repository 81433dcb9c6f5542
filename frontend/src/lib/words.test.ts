import { describe, expect, it } from 'vitest';
import { headingRuleName, modelName, plainName } from './words';

describe('plain words for API names', () => {
  it('request fields read as words with their unit', () => {
    expect(plainName('swath_width_m')).toBe('swath width (m)');
    expect(plainName('target_depth_mm')).toBe('target depth (mm)');
    expect(plainName('rate_at_lo_kg_ha')).toBe('rate at lo (kg/ha)');
    expect(plainName('rate_curve.ndvi_lo')).toBe('rate curve, NDVI lo');
    expect(plainName('plan_id')).toBe('plan');
    expect(plainName('confirm_flagged')).toBe('confirm flagged');
    expect(plainName('heading')).toBe('heading');
  });
  it('models and heading rules as the forms name them', () => {
    expect(modelName('nutrient_balance')).toBe('Nutrient balance (soil N)');
    expect(modelName('some_new_model')).toBe('some new model');
    expect(modelName(undefined)).toBe('–');
    expect(headingRuleName('longest_edge')).toBe('Parallel to the longest edge');
    expect(headingRuleName('angle')).toBe('Fixed heading');
  });
});
