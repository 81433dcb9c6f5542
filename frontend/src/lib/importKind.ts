/**
 * What a dropped file is, so one "Import…" takes every format FieldRx reads: field
 * boundaries (GeoJSON, KML, zipped Shapefile), ISO 11783-10 TASKDATA (zip or the XML with
 * its .BIN files), prescription Shapefiles, TimeLogs (TLGxxxxx.XML + .BIN) and as-applied
 * tables (CSV, zipped Shapefile). A zip is recognised by the names in its central directory
 * (read here, nothing is inflated); a zipped Shapefile can be any of three things, so the
 * user confirms the guess.
 */
export type ImportKind = 'fields' | 'isoxml' | 'rx-shapefile' | 'timelog' | 'as-applied';

export const KIND_LABELS: Record<ImportKind, string> = {
  fields: 'Field boundaries (GeoJSON, KML, Shapefile)',
  isoxml: 'ISO 11783-10 TASKDATA (farms, fields, prescriptions, TimeLogs)',
  'rx-shapefile': 'Prescription Shapefile (rates per zone)',
  timelog: 'ISO 11783-10 TimeLogs (as-applied records)',
  'as-applied': 'As-applied table (CSV or Shapefile records)',
};

/** Names of the members of a zip archive, from its end-of-central-directory record. */
export function zipNames(buf: ArrayBuffer): string[] {
  const v = new DataView(buf);
  const n = buf.byteLength;
  // EOCD: signature 0x06054b50, at most 65,535 bytes of comment after it
  let eocd = -1;
  for (let i = n - 22; i >= Math.max(0, n - 22 - 65_535); i--) {
    if (v.getUint32(i, true) === 0x06054b50) {
      eocd = i;
      break;
    }
  }
  if (eocd < 0) return [];
  const count = v.getUint16(eocd + 10, true);
  let p = v.getUint32(eocd + 16, true);
  const names: string[] = [];
  const dec = new TextDecoder();
  for (let k = 0; k < count && p + 46 <= n; k++) {
    if (v.getUint32(p, true) !== 0x02014b50) break;
    const nameLen = v.getUint16(p + 28, true);
    const extra = v.getUint16(p + 30, true);
    const comment = v.getUint16(p + 32, true);
    names.push(dec.decode(new Uint8Array(buf, p + 46, nameLen)));
    p += 46 + nameLen + extra + comment;
  }
  return names;
}

const base = (name: string) => name.split(/[\\/]/).pop()!.toUpperCase();

/** A zipped Shapefile's likely meaning from its file name (the user can change it). */
function shapefileGuess(fileName: string): ImportKind {
  const n = fileName.toLowerCase();
  if (/applied|asapplied|as_applied|coverage|log/.test(n)) return 'as-applied';
  if (/(^|[^a-z])rx([^a-z]|$)|rate|presc|vra|zones?/.test(n)) return 'rx-shapefile';
  return 'fields';
}

/**
 * The kind of an upload: the chosen files' names, and for a zip the names inside it.
 * Returns null with a reason when it is none of the formats.
 */
export function recognise(files: { name: string; members?: string[] }[]): { kind: ImportKind | null; why: string } {
  const names = files.flatMap((f) => [base(f.name), ...(f.members ?? []).map(base)]);
  if (names.includes('TASKDATA.XML')) return { kind: 'isoxml', why: 'holds TASKDATA.XML' };
  if (names.some((n) => /^TLG\d+\.XML$/.test(n))) return { kind: 'timelog', why: 'holds TLGxxxxx.XML TimeLogs' };
  if (names.some((n) => n.endsWith('.SHP'))) {
    const kind = shapefileGuess(files[0].name);
    return { kind, why: 'holds a Shapefile: say what it is' };
  }
  const one = base(files[0]?.name ?? '');
  if (one.endsWith('.CSV') || one.endsWith('.TXT')) return { kind: 'as-applied', why: 'a table of records' };
  if (/\.(GEOJSON|JSON|KML)$/.test(one)) return { kind: 'fields', why: 'field boundaries' };
  return { kind: null, why: `${files.map((f) => f.name).join(', ') || 'nothing'}: not a format FieldRx reads` };
}
