import registry from '../api/generated/import-formats.json';

/**
 * What a dropped file is, so one "Import…" takes every format FieldRx reads: field
 * boundaries (GeoJSON, KML, zipped Shapefile), ISO 11783-10 TASKDATA (zip or the XML with
 * its .BIN files), prescription Shapefiles, TimeLogs (TLGxxxxx.XML + .BIN) and as-applied
 * tables (CSV, zipped Shapefile). A zip is recognised by the names in its central directory
 * (read here, nothing is inflated); a zipped Shapefile can be any of three things, so the
 * user confirms the guess.
 */
export type ImportKind = 'fields' | 'isoxml' | 'rx-shapefile' | 'timelog' | 'as-applied';

interface Rule {
  priority: number;
  pattern: string;
  why: string;
  scope: string;
  file_name: string;
}

/** The server's import-format registry (`formats/import_formats.py`), as `scripts/gen-api.sh` wrote it. */
const FORMATS = (registry as { import_formats: { name: string; label: string; route: string; rules: Rule[] }[] }).import_formats;

export const KIND_LABELS = Object.fromEntries(FORMATS.map((f) => [f.name, f.label])) as Record<ImportKind, string>;

/** Every format's rules, lowest priority first: the order they are tried in (as on the server). */
const RULES = FORMATS.flatMap((f) => f.rules.map((r) => ({ ...r, kind: f.name as ImportKind, re: new RegExp(r.pattern), name: r.file_name ? new RegExp(r.file_name) : null }))).sort(
  (a, b) => a.priority - b.priority,
);

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

/**
 * The kind of an upload: the chosen files' names, and for a zip the names inside it, tried
 * against the registry's rules in their order (a zipped Shapefile's kind is guessed from
 * the file's name; the user can change it). Returns null with a reason when it is none of
 * the formats.
 */
export function recognise(files: { name: string; members?: string[] }[]): { kind: ImportKind | null; why: string } {
  const names = files.flatMap((f) => [base(f.name), ...(f.members ?? []).map(base)]);
  const first = files[0]?.name ?? '';
  for (const r of RULES) {
    const pool = r.scope === 'first' ? [base(first)] : names;
    if (!pool.some((n) => r.re.test(n))) continue;
    if (r.name && !r.name.test(first.toLowerCase())) continue;
    return { kind: r.kind, why: r.why };
  }
  return { kind: null, why: `${files.map((f) => f.name).join(', ') || 'nothing'}: not a format FieldRx reads` };
}
