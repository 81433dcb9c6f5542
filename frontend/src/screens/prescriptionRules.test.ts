// Issue 15: no screen keeps more than ~8 pieces of local state, none adds map layers itself.
// Checked on the prescription screen, its form and the components they are built from.
import { readFileSync } from 'node:fs';
import { join } from 'node:path';
import { describe, expect, it } from 'vitest';
import { outsideMeter } from '../lib/rxform';

const SRC = join(__dirname, '..');
const FILES = [
  'screens/Prescription.tsx',
  'screens/RxForm.tsx',
  'components/SoilZonesForm.tsx',
  'components/ImageryRxForm.tsx',
  'components/ProductPicker.tsx',
  'components/RxModelFields.tsx',
  'components/RxSummaryPanel.tsx',
  'components/ZonesTable.tsx',
  'components/VersionDiff.tsx',
  'components/VersionNote.tsx',
  'components/UndoRedo.tsx',
  'components/CellEditPanel.tsx',
  'components/ZonePaintPanel.tsx',
  'components/SendJobPanel.tsx',
];

describe('prescription screen rules', () => {
  for (const f of FILES) {
    it(`${f}: at most 8 useState, no addLayer / addSource`, () => {
      const text = readFileSync(join(SRC, f), 'utf8');
      expect((text.match(/useState[<(]/g) ?? []).length).toBeLessThanOrEqual(8);
      expect(text).not.toMatch(/\.(addLayer|addSource)\(/);
    });
  }
});

describe('outsideMeter', () => {
  it('names the rates a machine cannot meter; 0 (off) is fine', () => {
    expect(outsideMeter({ rate_min_kg_ha: 0, rate_max_kg_ha: 700 }, 583.6, 882.1)).toBeNull();
    expect(outsideMeter({ rate_min_kg_ha: 500, rate_max_kg_ha: 900 }, 583.6, 882.1)).toBe(
      'lowest rate 500.0 kg/ha is below 583.6 kg/ha; highest rate 900.0 kg/ha is above 882.1 kg/ha',
    );
  });
});
