import { describe, expect, it } from 'vitest';
import { recognise, zipNames } from './importKind';

/** A stored (uncompressed) zip with empty members, written by hand: local headers,
 * central directory and end record, as any zip tool writes them. */
function zipOf(names: string[]): ArrayBuffer {
  const enc = new TextEncoder();
  const parts: number[] = [];
  const central: number[] = [];
  const u16 = (a: number[], x: number) => a.push(x & 255, (x >> 8) & 255);
  const u32 = (a: number[], x: number) => a.push(x & 255, (x >> 8) & 255, (x >> 16) & 255, (x >>> 24) & 255);
  for (const name of names) {
    const nb = [...enc.encode(name)];
    const offset = parts.length;
    u32(parts, 0x04034b50);
    for (let i = 0; i < 11; i++) u16(parts, 0); // version .. sizes (all 0 for an empty member)
    u16(parts, nb.length);
    u16(parts, 0);
    parts.push(...nb);
    u32(central, 0x02014b50);
    for (let i = 0; i < 12; i++) u16(central, 0);
    u16(central, nb.length);
    u16(central, 0);
    u16(central, 0);
    u16(central, 0);
    u16(central, 0);
    u32(central, 0);
    u32(central, offset);
    central.push(...nb);
  }
  const out = [...parts, ...central];
  u32(out, 0x06054b50);
  u16(out, 0);
  u16(out, 0);
  u16(out, names.length);
  u16(out, names.length);
  u32(out, central.length);
  u32(out, parts.length);
  u16(out, 0);
  return new Uint8Array(out).buffer;
}

describe('import recognition', () => {
  it('reads the member names of a zip', () => {
    expect(zipNames(zipOf(['TASKDATA/TASKDATA.XML', 'TASKDATA/GRD00001.BIN']))).toEqual([
      'TASKDATA/TASKDATA.XML',
      'TASKDATA/GRD00001.BIN',
    ]);
    expect(zipNames(new ArrayBuffer(30))).toEqual([]);
  });

  it('tells the formats apart', () => {
    expect(recognise([{ name: 'export.zip', members: ['TASKDATA/TASKDATA.XML'] }]).kind).toBe('isoxml');
    expect(recognise([{ name: 'TASKDATA.XML' }, { name: 'GRD00001.BIN' }]).kind).toBe('isoxml');
    expect(recognise([{ name: 'TLG00001.xml' }, { name: 'TLG00001.bin' }]).kind).toBe('timelog');
    expect(recognise([{ name: 'logs.zip', members: ['TLG00001.XML', 'TLG00001.BIN'] }]).kind).toBe('timelog');
    expect(recognise([{ name: 'north_rx.zip', members: ['a.shp', 'a.dbf'] }]).kind).toBe('rx-shapefile');
    expect(recognise([{ name: 'as_applied.zip', members: ['a.shp'] }]).kind).toBe('as-applied');
    expect(recognise([{ name: 'fields.zip', members: ['a.shp'] }]).kind).toBe('fields');
    expect(recognise([{ name: 'applied.csv' }]).kind).toBe('as-applied');
    expect(recognise([{ name: 'north.kml' }]).kind).toBe('fields');
    const none = recognise([{ name: 'photo.png' }]);
    expect(none.kind).toBeNull();
    expect(none.why).toContain('photo.png');
  });
});
