// The machine's meterable range beside the prescription's rates.
// (The screens' state and map-layer rules are checked for every screen and component in
// screens.test.ts.)
import { describe, expect, it } from 'vitest';
import { outsideMeter } from '../lib/rxform';

describe('outsideMeter', () => {
  it('names the rates a machine cannot meter; 0 (off) is fine', () => {
    expect(outsideMeter({ rate_min_kg_ha: 0, rate_max_kg_ha: 700 }, 583.6, 882.1)).toBeNull();
    expect(outsideMeter({ rate_min_kg_ha: 500, rate_max_kg_ha: 900 }, 583.6, 882.1)).toBe(
      'lowest rate 500.0 kg/ha is below 583.6 kg/ha; highest rate 900.0 kg/ha is above 882.1 kg/ha',
    );
  });
});
