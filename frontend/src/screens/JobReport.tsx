import { useCallback, useEffect, useMemo, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { call, client, type FieldFeature, type Job, type Prescription, type Schemas } from '../api/client';
import { Legend } from '../components/Legend';
import { ErrorBox, Kv } from '../components/Status';
import { ACCURACY_BREAKS, RED_GREEN, classColors, legendEntries, niceBreaks, stepExpression } from '../lib/colors';
import { asGeoJSON, bboxOf, bearingDeg } from '../lib/geo';
import { normaliseTrack, type TrackPoint } from '../lib/track';
import { formatArea, formatDuration, formatMass, formatPercent, formatRate } from '../lib/units';
import { MapView } from '../map/MapView';
import { absoluteApiUrl, fitTo, setGeoJSON } from '../map/setup';
import { replaceVectorSource } from '../map/grid';
import { KindReport } from './KindReport';

type View = 'applied' | 'accuracy';
const EMPTY: GeoJSON.FeatureCollection = { type: 'FeatureCollection', features: [] };
const FINAL = new Set(['completed', 'aborted']);
const MAX_POINTS = 200_000;

/** As-applied map (job vector tiles), per-cell accuracy, totals, and a replay of the records. */
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
  const [report, setReport] = useState<Schemas['AsAppliedReport'] | null>(null);
  const [points, setPoints] = useState<TrackPoint[]>([]);
  const [view, setView] = useState<View>('applied');
  const [tIdx, setTIdx] = useState(-1);
  const [follow, setFollow] = useState(true);
  const [error, setError] = useState<unknown>(null);
  const [tick, setTick] = useState(0);
  const mapRef = useRef<maplibregl.Map | null>(null);
  const nextOffset = useRef(0);

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
      const path = { job_id: jobId };
      const j = await call(client.GET('/api/v1/jobs/{job_id}', { params: { path } }));
      setJob(j);
      const rep = await call(client.GET('/api/v1/jobs/{job_id}/report', { params: { path, query: { cells: false } } }));
      if (!('kind' in rep)) setReport(rep);
      // New records since the last poll (the endpoint pages in time order).
      for (let page = 0; page < 10 && nextOffset.current < MAX_POINTS; page++) {
        const r = await call(
          client.GET('/api/v1/jobs/{job_id}/as-applied', { params: { path, query: { limit: 20000, offset: nextOffset.current } } }),
        );
        const pts = normaliseTrack(r);
        if (pts.length) setPoints((cur) => [...cur, ...pts]);
        nextOffset.current += r.features.length;
        if (!r.next_offset) break;
      }
      setTick((t) => t + 1);
    } catch (e) {
      setError(e);
    }
  }, [jobId]);

  useEffect(() => {
    void refresh();
  }, [refresh]);
  useEffect(() => {
    if (job && FINAL.has(job.state) && tick > 1) return;
    const t = setTimeout(() => void refresh(), 4000);
    return () => clearTimeout(t);
  }, [tick, job, refresh]);

  useEffect(() => {
    if (follow) setTIdx(points.length - 1);
  }, [points.length, follow]);

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

  useEffect(() => {
    const map = mapRef.current;
    if (map?.getLayer('job-fill')) map.setPaintProperty('job-fill', 'fill-color', fill as never);
  }, [fill]);

  // Reload tiles as records arrive (the server answers no-cache tiles).
  useEffect(() => {
    const map = mapRef.current;
    const src = map?.getSource('job') as maplibregl.VectorTileSource | undefined;
    if (src && tick > 1 && !(job && FINAL.has(job.state) && tick > 3)) src.setTiles([tilesUrl(jobId, tick)]);
  }, [tick]); // eslint-disable-line react-hooks/exhaustive-deps

  const [mapReady, setMapReady] = useState(false);
  useEffect(() => {
    const map = mapRef.current;
    if (!map || !field) return;
    setGeoJSON(map, 'field', asGeoJSON(field));
    fitTo(map, bboxOf(field));
    // Cell tiles only once the view is on the field; below the field outline and the replay.
    if (!map.getSource('job')) {
      replaceVectorSource(map, 'job', tilesUrl(jobId, tick), [
        { id: 'job-fill', type: 'fill', source: 'job', 'source-layer': 'cells', paint: { 'fill-color': fill as never, 'fill-opacity': 0.85 } },
      ]);
      for (const l of ['field-line', 'trail', 'replay']) if (map.getLayer(l)) map.moveLayer(l);
    }
  }, [field, mapReady]); // eslint-disable-line react-hooks/exhaustive-deps

  const cur = tIdx >= 0 ? points[tIdx] : undefined;
  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    const upto = points.slice(0, tIdx + 1).filter((p) => p.lon != null && p.lat != null);
    setGeoJSON(map, 'trail', {
      type: 'Feature',
      properties: {},
      geometry: { type: 'LineString', coordinates: upto.map((p) => [p.lon!, p.lat!]) },
    });
    const n = upto.length;
    const heading = n > 1 ? bearingDeg([upto[n - 2].lon!, upto[n - 2].lat!], [upto[n - 1].lon!, upto[n - 1].lat!]) : 0;
    setGeoJSON(
      map,
      'replay',
      cur?.lon != null && cur.lat != null
        ? { type: 'Feature', properties: { heading: cur.heading_deg ?? heading }, geometry: { type: 'Point', coordinates: [cur.lon, cur.lat] } }
        : EMPTY,
    );
  }, [points, tIdx, cur]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'field', field ? asGeoJSON(field) : EMPTY);
    map.addLayer({ id: 'field-line', type: 'line', source: 'field', paint: { 'line-color': '#222', 'line-width': 2 } });
    setGeoJSON(map, 'trail', EMPTY);
    map.addLayer({ id: 'trail', type: 'line', source: 'trail', paint: { 'line-color': '#111', 'line-width': 1.2, 'line-opacity': 0.55 } });
    setGeoJSON(map, 'replay', EMPTY);
    map.addLayer({
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
    setMapReady(true);
  };

  const r: Partial<Schemas['AsAppliedReport']> = report ?? {};
  /** Prescribed cells nothing landed in (the job-end alert lists them too). */
  const notApplied = (rep: Partial<Schemas['AsAppliedReport']>): string => {
    const seqs = rep.not_applied_seqs ?? [];
    if (!seqs.length) return report ? 'none' : '–';
    const shown = seqs.slice(0, 30).join(', ');
    return `${seqs.length}: seq ${shown}${seqs.length > 30 ? ` and ${seqs.length - 30} more` : ''}`;
  };
  const cov = r.coverage_pct;
  const acc = r.mean_accuracy_pct;
  return (
    <div className="split">
      <aside className="panel">
        <p>
          <a href="#/jobs">← Jobs</a>
        </p>
        <h2>Job #{jobId} report</h2>
        <ErrorBox error={error} />
        <Kv
          items={[
            ['State', job?.state ?? '–', 'report-state'],
            ['Machine', job ? <a href={`#/machines/${job.machine_id}`}>#{job.machine_id}</a> : '–'],
            [
              'Prescription',
              job ? <a href={`#/prescriptions/${job.prescription_id}`}>#{job.prescription_id} v{job.prescription_version}</a> : '–',
            ],
            [
              'Flagged cells',
              job?.flagged_cells ? `${String(job.flagged_cells)}${job.flagged_confirmed ? ' (sent on confirmation)' : ''}` : '–',
              'report-flagged',
            ],
            ['Cells applied', `${r.cells_applied ?? '–'} / ${r.cells_planned ?? '–'}`, 'report-cells'],
            ['Coverage', cov != null ? formatPercent(cov / 100) : '–', 'report-coverage'],
            ['Planned', formatMass(r.planned_total_kg)],
            ['Applied', formatMass(r.applied_total_kg), 'report-applied-kg'],
            ['Outside cells', formatMass(r.applied_outside_cells_kg)],
            ['Mean accuracy', acc != null ? `${acc.toFixed(1)} %` : '–', 'report-accuracy'],
            ['Worst cell', r.min_accuracy_pct != null ? `${r.min_accuracy_pct.toFixed(1)} %` : '–'],
            ['Time worked', formatDuration(r.time_worked_s)],
            ['Records', String(r.n_records ?? points.length), 'report-records'],
            ['Never applied', notApplied(r), 'report-not-applied'],
            ['Field', field ? `${field.properties.name} (${formatArea(field.properties.area_m2)})` : '–'],
          ]}
        />
        <div className="row" role="group">
          <button data-testid="view-applied" className={view === 'applied' ? 'on' : ''} onClick={() => setView('applied')}>
            As applied
          </button>
          <button data-testid="view-accuracy" className={view === 'accuracy' ? 'on' : ''} onClick={() => setView('accuracy')}>
            Accuracy
          </button>
        </div>
        <Legend
          entries={legend}
          title={view === 'applied' ? 'Applied rate (kg/ha)' : 'Accuracy (100 % = target met)'}
          testid="report-legend"
        />
        <h3>Track replay</h3>
        <input
          data-testid="replay-slider"
          type="range"
          min={0}
          max={Math.max(0, points.length - 1)}
          value={Math.max(0, tIdx)}
          disabled={points.length === 0}
          onChange={(e) => {
            const v = Number(e.target.value);
            setFollow(v >= points.length - 1);
            setTIdx(v);
          }}
          style={{ width: '100%' }}
        />
        <p className="muted small" data-testid="replay-time">
          {cur
            ? `${new Date(cur.t * 1000).toISOString().replace('T', ' ').slice(0, 19)} UTC · target ${formatRate(cur.target_rate_kg_ha)} · applied ${formatRate(cur.applied_rate_kg_ha)}`
            : 'no records yet'}
        </p>
        <p className="muted small" data-testid="report-points">
          {points.length} as-applied records
        </p>
      </aside>
      <MapView name="report" onReady={onReady} fieldId={field?.id} />
    </div>
  );
}

function tilesUrl(jobId: number, v: number): string {
  return absoluteApiUrl(`/api/v1/tiles/jobs/${jobId}/{z}/{x}/{y}.mvt?v=${v}`);
}
