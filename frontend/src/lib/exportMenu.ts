import type { Schemas } from '../api/client';

export type ExportFormatInfo = Schemas['ExportFormatOut'];

/** One button of an export menu: the query after `format=`, its label, a file name ending. */
export interface ExportEntry {
  /** `format` plus any variant's parameters, e.g. `shapefile&profile=deere` */
  query: string;
  label: string;
  /** the file's name ending after the server's stem, for a name when the server gives none */
  extension: string;
}

/**
 * The export menu of a subject (`prescription` or `job`) from the server's registry
 * (`GET /export-formats`), in its order: each format that exports the subject, then
 * (prescriptions) its variants, after every plain format as the terminal layouts.
 */
export function exportMenu(formats: readonly ExportFormatInfo[], subject: 'prescription' | 'job'): ExportEntry[] {
  const mine = formats.filter((f) => f.subjects.includes(subject));
  const ext = (f: ExportFormatInfo) => (subject === 'job' ? f.job_extension : f.extension);
  const plain = mine.map((f) => ({ query: f.name, label: f.label, extension: ext(f) }));
  if (subject === 'job') return plain;
  const variants = mine.flatMap((f) =>
    f.variants.map((v) => ({
      query: [f.name, ...Object.entries(v.params).map(([k, val]) => `${k}=${encodeURIComponent(val)}`)].join('&'),
      label: v.label,
      extension: ext(f),
    })),
  );
  return [...plain, ...variants];
}

/** The download extension of a file name ending (`_shp.zip` -> `zip`). */
export function fileType(extension: string): string {
  return extension.split('.').pop() ?? '';
}
