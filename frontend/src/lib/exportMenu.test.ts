import { describe, expect, it } from 'vitest';
import { exportMenu, fileType, type ExportFormatInfo } from './exportMenu';

const fmt = (name: string, subjects: string[], extra: Partial<ExportFormatInfo> = {}): ExportFormatInfo => ({
  name,
  label: name.toUpperCase(),
  media_type: 'application/zip',
  subjects,
  extension: `.${name}`,
  job_extension: `_job.${name}`,
  default_name: `x.${name}`,
  variants: [],
  ...extra,
});

const FORMATS = [
  fmt('geojson', ['prescription']),
  fmt('csv', ['prescription', 'job']),
  fmt('shapefile', ['prescription', 'job'], { extension: '_shp.zip', variants: [{ label: 'Deere', params: { profile: 'deere' } }] }),
  fmt('job', ['package']),
];

describe('exportMenu', () => {
  it('lists a subject’s formats in the server’s order, then the variants', () => {
    expect(exportMenu(FORMATS, 'prescription').map((e) => e.query)).toEqual(['geojson', 'csv', 'shapefile', 'shapefile&profile=deere']);
    expect(exportMenu(FORMATS, 'prescription')[3]).toEqual({ query: 'shapefile&profile=deere', label: 'Deere', extension: '_shp.zip' });
  });

  it('gives a job its formats, with their as-applied file endings and no variants', () => {
    expect(exportMenu(FORMATS, 'job')).toEqual([
      { query: 'csv', label: 'CSV', extension: '_job.csv' },
      { query: 'shapefile', label: 'SHAPEFILE', extension: '_job.shapefile' },
    ]);
  });

  it('is empty before the formats have loaded', () => {
    expect(exportMenu([], 'prescription')).toEqual([]);
  });
});

describe('fileType', () => {
  it('is the last extension', () => {
    expect(fileType('_TASKDATA_grid.zip')).toBe('zip');
    expect(fileType('.geojson')).toBe('geojson');
  });
});
