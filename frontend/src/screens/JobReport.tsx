import { useCallback, useEffect, useMemo, useState } from 'react';
import { flushSync } from 'react-dom';
import type * as maplibregl from 'maplibre-gl';
import { call, client, type FieldFeature, type Job, type Prescription } from '../api/client';
import { ExportButtons } from '../components/ExportButtons';
import { Legend } from '../components/Legend';
import { PrintReport, mapSnapshot } from '../components/PrintReport';
import { ReportLoading, useJobReport, type AsAppliedReport } from '../components/ReportLoader';
import { ErrorBox, Kv } from '../components/Status';
import { TrackReplay } from '../components/TrackReplay';
import { ACCURACY_BREAKS, RED_GREEN, classColors, legendEntries, niceBreaks, stepExpression } from '../lib/colors';
import { asGeoJSON, bboxOf } from '../lib/geo';
import { formatArea, formatDuration, formatMass, formatPercent } from '../lib/units';
import { MapView } from '../map/MapView';
import { absoluteApiUrl, fitTo, setGeoJSON } from '../map/setup';
import { replaceVectorSource } from '../map/grid';
import { KindReport } from './KindReport';

type View = 'applied' | 'accuracy';
const EMPTY: GeoJSON.FeatureCollection = { type: 'FeatureCollection', features: [] };
const FINAL = new Set(['completed', 'aborted']);

/** As-applied map (job vector tiles), per-cell accuracy, totals, exports, a printable report
 * and a paged replay of the records. */
export function JobReport({ jobId }: { jobId: number }) {
  const [kindJob, setKindJob] = useState<Job | null | undefined>(undefined);
  useEffect(() => {
    call(client.GET('/api/v1/jobs/{job_id}', { params: { path: { job_id: jobId } } }))
      .then((j) => setKindJob(j.kind && j.kind !== 'prescription_map' ? j : null))
      .catch(() => setKindJob(null));
  }, [jobId]);
  if (kindJob === undefined) return <p className="muted">Loading…</p>;
  if (kindJob) return <KindReport job={kindJob} />;
  return <PrescriptionJobReport jobId={jobId} />;
}

/** The prescription-map (seed 001) job report. */
function PrescriptionJobReport({ jobId }: { jobId: number }) {
  const [job, setJob] = useState<Job | null>(null);
  const [rx, setRx] = useState<Prescription | null>(null);
  const [field, setField] = useState<FieldFeature | null>(null);
  const [view, setView] = useState<View>('applied');
  const [error, setError] = useState<unknown>(null);
  const [tick, setTick] = useState(0);
  const [map, setMap] = useState<maplibregl.Map | null>(null);
  const [printImage, setPrintImage] = useState('');
  const { report, task, refresh: refreshReport } = useJobReport(jobId);

  // Static context: job -> prescription (for the colour scale) -> plan -> field (to fit the map).
  useEffect(() => {
    (async () => {
      try {
        const j = await call(client.GET('/api/v1/jobs/{job_id}', { params: { path: { job_id: jobId } } }));
        setJob(j);
        if (j.prescription_id == null) return;
        const r = await call(client.GET('/api/v1/prescriptions/{rx_id}', { params: { path: { rx_id: j.prescription_id } } }));
        setRx(r);
        const p = await call(client.GET('/api/v1/plans/{plan_id}', { params: { path: { plan_id: r.plan_id } } }));
        setField(await call(client.GET('/api/v1/fields/{field_id}', { params: { path: { field_id: p.field_id } } })));
      } catch (e) {
        setError(e);
      }
    })();
  }, [jobId]);

  const refresh = useCallback(async () => {
    try {
      setJob(await call(client.GET('/api/v1/jobs/{job_id}', { params: { path: { job_id: jobId } } })));
      await refreshReport();
      setTick((t) => t + 1);
    } catch (e) {
      setError(e);
    }
  }, [jobId, refreshReport]);

  useEffect(() => {
    void refresh();
  }, [refresh]);
  useEffect(() => {
    if (job && FINAL.has(job.state) && tick > 1) return;
    const t = setTimeout(() => void refresh(), 4000);
    return () => clearTimeout(t);
  }, [tick, job, refresh]);

  const lo = rx?.summary.rate_min_kg_ha ?? 0;
  const hi = rx?.summary.rate_max_kg_ha ?? 1000;
  const rateBreaks = useMemo(() => niceBreaks(lo, hi === lo ? lo + 1 : hi, 6), [lo, hi]);
  const rateColors = classColors(rateBreaks.length - 1);
  const accColors = classColors(ACCURACY_BREAKS.length - 1, RED_GREEN);
  const fill = useMemo(() => {
    const byRate = stepExpression('applied_rate', rateBreaks, rateColors);
    const byAcc = stepExpression('accuracy', ACCURACY_BREAKS, accColors);
    // Cells nobody drove over yet stay light grey.
    return ['case', ['<=', ['to-number', ['get', 'n_records'], 0], 0], '#dddddd', view === 'applied' ? byRate : byAcc];
  }, [view, rateBreaks, rateColors, accColors]);
  const legend =
    view === 'applied'
      ? legendEntries(rateBreaks, rateColors, (v) => v.toFixed(0))
      : legendEntries(ACCURACY_BREAKS, accColors, (v) => `${v} %`);
  const legendTitle = view === 'applied' ? 'Applied rate (kg/ha)' : 'Accuracy (100 % = target met)';

  useEffect(() => {
    if (map?.getLayer('job-fill')) map.setPaintProperty('job-fill', 'fill-color', fill as never);
  }, [fill, map]);

  // Reload tiles as records arrive (the server answers no-cache tiles).
  useEffect(() => {
    const src = map?.getSource('job') as maplibregl.VectorTileSource | undefined;
    if (src && tick > 1 && !(job && FINAL.has(job.state) && tick > 3)) src.setTiles([tilesUrl(jobId, tick)]);
  }, [tick]); // eslint-disable-line react-hooks/exhaustive-deps

  const haveReport = report != null;
  useEffect(() => {
    if (!map || !field) return;
    setGeoJSON(map, 'field', asGeoJSON(field));
    fitTo(map, bboxOf(field));
    // Cell tiles only once the view is on the field and the report is known (a large job's
    // tiles then read the report task's snapshot instead of computing the report again);
    // below the field outline and the replay.
    if (haveReport && !map.getSource('job')) {
      replaceVectorSource(map, 'job', tilesUrl(jobId, tick), [
        { id: 'job-fill', type: 'fill', source: 'job', 'source-layer': 'cells', paint: { 'fill-color': fill as never, 'fill-opacity': 0.85 } },
      ]);
      for (const l of ['field-line', 'trail', 'replay']) if (map.getLayer(l)) map.moveLayer(l);
    }
  }, [field, map, haveReport]); // eslint-disable-line react-hooks/exhaustive-deps

  // Printing (the button or the browser's own menu): a still of the map goes on the page.
  useEffect(() => {
    const before = () => setPrintImage(mapSnapshot(map));
    window.addEventListener('beforeprint', before);
    return () => window.removeEventListener('beforeprint', before);
  }, [map]);
  const print = () => {
    flushSync(() => setPrintImage(mapSnapshot(map)));
    window.print();
  };

  const onReady = (m: maplibregl.Map) => {
    setGeoJSON(m, 'field', field ? asGeoJSON(field) : EMPTY);
    m.addLayer({ id: 'field-line', type: 'line', source: 'field', paint: { 'line-color': '#222', 'line-width': 2 } });
    setGeoJSON(m, 'trail', EMPTY);
    m.addLayer({ id: 'trail', type: 'line', source: 'trail', paint: { 'line-color': '#111', 'line-width': 1.2, 'line-opacity': 0.55 } });
    setGeoJSON(m, 'replay', EMPTY);
    m.addLayer({
      id: 'replay',
      type: 'symbol',
      source: 'replay',
      layout: {
        'icon-image': 'arrow',
        'icon-rotate': ['get', 'heading'],
        'icon-rotation-alignment': 'map',
        'icon-size': 0.8,
        'icon-allow-overlap': true,
      },
      paint: { 'icon-color': '#d7263d', 'icon-halo-color': '#fff', 'icon-halo-width': 2 },
    });
    setMap(m);
  };

  const r: Partial<AsAppliedReport> = report ?? {};
  /** Before the first report: "…" (loading), not "–" or 0 that read as "nothing there". */
  const v = (x: React.ReactNode | undefined | null): React.ReactNode => (report ? (x ?? '–') : '…');
  /** Prescribed cells nothing landed in (the job-end alert lists them too). */
  const notApplied = (rep: Partial<AsAppliedReport>): string => {
    const seqs = rep.not_applied_seqs ?? [];
    if (!seqs.length) return report ? 'none' : '…';
    const shown = seqs.slice(0, 30).join(', ');
    return `${seqs.length}: seq ${shown}${seqs.length > 30 ? ` and ${seqs.length - 30} more` : ''}`;
  };
  const cov = r.coverage_pct;
  const acc = r.mean_accuracy_pct;
  return (
    <div className="split report-page">
      <aside className="panel">
        <p className="screen-only">
          <a href="#/jobs">← Jobs</a>
        </p>
        <h2>Job #{jobId} report</h2>
        <ErrorBox error={error} />
        {!report && <ReportLoading task={task} onDone={() => void refresh()} />}
        <div aria-busy={!report}>
          <Kv
            items={[
              ['State', job?.state ?? '–', 'report-state'],
              ['Machine', job ? <a href={`#/machines/${job.machine_id}`}>{job.machine_name ?? `#${job.machine_id}`}</a> : '–', 'report-machine'],
              [
                'Prescription',
                job ? <a href={`#/prescriptions/${job.prescription_id}`}>#{job.prescription_id} v{job.prescription_version}</a> : '–',
              ],
              ['Product', rx?.product || job?.product || '–', 'report-product'],
              [
                'Flagged cells',
                job?.flagged_cells ? `${String(job.flagged_cells)}${job.flagged_confirmed ? ' (sent on confirmation)' : ''}` : '–',
                'report-flagged',
              ],
              ['Cells applied', report ? `${r.cells_applied ?? '–'} / ${r.cells_planned ?? '–'}` : '…', 'report-cells'],
              ['Coverage', v(cov != null ? formatPercent(cov / 100) : null), 'report-coverage'],
              ['Planned', v(formatMass(r.planned_total_kg))],
              ['Applied', v(formatMass(r.applied_total_kg)), 'report-applied-kg'],
              ['Outside cells', v(formatMass(r.applied_outside_cells_kg))],
              ['Mean accuracy', v(acc != null ? `${acc.toFixed(1)} %` : null), 'report-accuracy'],
              ['Worst cell', v(r.min_accuracy_pct != null ? `${r.min_accuracy_pct.toFixed(1)} %` : null)],
              ['Time worked', v(formatDuration(r.time_worked_s))],
              ['Records', v(r.n_records != null ? String(r.n_records) : null), 'report-records'],
              ['Never applied', notApplied(r), 'report-not-applied'],
              ['Field', field ? `${field.properties.name} (${formatArea(field.properties.area_m2)})` : '–'],
            ]}
          />
        </div>
        <div className="row screen-only" role="group">
          <button data-testid="view-applied" className={view === 'applied' ? 'on' : ''} onClick={() => setView('applied')}>
            As applied
          </button>
          <button data-testid="view-accuracy" className={view === 'accuracy' ? 'on' : ''} onClick={() => setView('accuracy')}>
            Accuracy
          </button>
          <button data-testid="report-print" onClick={print} disabled={!report}>
            Print report
          </button>
        </div>
        <ExportButtons
          path={`/jobs/${jobId}/export`}
          formats={[
            { format: 'csv', label: 'CSV', fallback: `job${jobId}_as_applied.csv` },
            { format: 'shapefile', label: 'Shapefile', fallback: `job${jobId}_as_applied.zip` },
            { format: 'isoxml', label: 'ISOXML', fallback: `job${jobId}_TASKDATA.zip` },
          ]}
        />
        <Legend entries={legend} title={legendTitle} testid="report-legend" />
        <TrackReplay jobId={jobId} map={map} tick={tick} />
      </aside>
      <MapView name="report" onReady={onReady} fieldId={field?.id} />
      <PrintReport job={job} field={field} rx={rx} report={report} mapImage={printImage} legend={legend} legendTitle={legendTitle} />
    </div>
  );
}

function tilesUrl(jobId: number, v: number): string {
  return absoluteApiUrl(`/api/v1/tiles/jobs/${jobId}/{z}/{x}/{y}.mvt?v=${v}`);
}
