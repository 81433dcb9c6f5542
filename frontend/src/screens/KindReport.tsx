import { useEffect, useMemo, useRef, useState } from 'react';
import { ReportLoading } from '../components/ReportLoader';
import type * as maplibregl from 'maplibre-gl';
import { call, client, type FieldFeature, type Job } from '../api/client';
import { Legend } from '../components/Legend';
import { ErrorBox, Kv } from '../components/Status';
import { classColors, legendEntries, niceBreaks, stepExpression } from '../lib/colors';
import { asGeoJSON, bboxOf } from '../lib/geo';
import { cellValue, KIND_LABELS, type DepthBand, type JobKind, type ShaftBand } from '../lib/jobkinds';
import { MapView } from '../map/MapView';
import { fitTo, setGeoJSON } from '../map/setup';

const EMPTY: GeoJSON.FeatureCollection = { type: 'FeatureCollection', features: [] };
const FINAL = new Set(['completed', 'aborted']);
const f1 = (v: unknown, d = 1) => (typeof v === 'number' && Number.isFinite(v) ? v.toFixed(d) : '–');

/** Report of a sensor job (seed 000 / 002): the paper's Table 3 and the NDVI / rate / depth maps. */
export function KindReport({ job }: { job: Job }) {
  const kind = job.kind as JobKind;
  const [report, setReport] = useState<Record<string, unknown> | null>(null);
  const [cells, setCells] = useState<GeoJSON.Feature[]>([]);
  const [field, setField] = useState<FieldFeature | null>(null);
  const [view, setView] = useState(kind === 'ndvi_topdress' ? 'ndvi' : 'depth');
  const [error, setError] = useState<unknown>(null);
  const [tick, setTick] = useState(0);
  const mapRef = useRef<maplibregl.Map | null>(null);
  const [mapReady, setMapReady] = useState(false);

  useEffect(() => {
    (async () => {
      try {
        if (job.plan_id == null) return;
        const path = { plan_id: job.plan_id };
        const p = await call(client.GET('/api/v1/plans/{plan_id}', { params: { path } }));
        setField(await call(client.GET('/api/v1/fields/{field_id}', { params: { path: { field_id: p.field_id } } })));
        const feats: GeoJSON.Feature[] = [];
        for (let off = 0; off < 20000; off += 1000) {
          const r = await call(client.GET('/api/v1/plans/{plan_id}/cells', { params: { path, query: { limit: 1000, offset: off } } }));
          feats.push(...asGeoJSON(r).features);
          if (r.features.length < 1000) break;
        }
        setCells(feats);
      } catch (e) {
        setError(e);
      }
    })();
  }, [job.plan_id]);

  useEffect(() => {
    let stop = false;
    call(client.GET('/api/v1/jobs/{job_id}/report', { params: { path: { job_id: job.id } } }))
      .then((r) => !stop && setReport(r as Record<string, unknown>))
      .catch((e) => !stop && setError(e));
    if (FINAL.has(job.state) && tick > 0) return;
    const t = setTimeout(() => setTick((x) => x + 1), 4000);
    return () => {
      stop = true;
      clearTimeout(t);
    };
  }, [job.id, job.state, tick]);

  const byseq = useMemo(() => {
    const m = new Map<number, Record<string, unknown>>();
    for (const c of (report?.cells as Record<string, unknown>[] | undefined) ?? []) m.set(Number(c.seq), c);
    return m;
  }, [report]);
  const values = [...byseq.values()].map((c) => cellValue(kind, view, c)).filter((v): v is number => v != null);
  const lo = values.length ? Math.min(...values) : 0;
  const hi = values.length ? Math.max(...values) : 1;
  const breaks = useMemo(() => niceBreaks(lo, hi > lo ? hi : lo + 1, 6), [lo, hi]);
  const colors = classColors(breaks.length - 1);

  useEffect(() => {
    const map = mapRef.current;
    if (!map || !mapReady) return;
    const fc: GeoJSON.FeatureCollection = {
      type: 'FeatureCollection',
      features: cells.map((f) => {
        const c = byseq.get(Number(f.properties?.seq));
        return { ...f, properties: { ...f.properties, v: c ? cellValue(kind, view, c) : null } };
      }),
    };
    setGeoJSON(map, 'kcells', fc);
    const fill = ['case', ['==', ['get', 'v'], null], '#dddddd', stepExpression('v', breaks, colors)];
    if (!map.getLayer('kcells-fill')) {
      map.addLayer({ id: 'kcells-fill', type: 'fill', source: 'kcells', paint: { 'fill-color': fill as never, 'fill-opacity': 0.85 } });
      if (map.getLayer('field-line')) map.moveLayer('field-line');
    } else map.setPaintProperty('kcells-fill', 'fill-color', fill as never);
    if (field) fitTo(map, bboxOf(field));
  }, [cells, byseq, view, breaks, colors, field, mapReady, kind]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'field', field ? asGeoJSON(field) : EMPTY);
    map.addLayer({ id: 'field-line', type: 'line', source: 'field', paint: { 'line-color': '#222', 'line-width': 2 } });
    setMapReady(true);
  };
  useEffect(() => {
    const map = mapRef.current;
    if (map && field) setGeoJSON(map, 'field', asGeoJSON(field));
  }, [field]);

  const r = report ?? {};
  const s = (job.settings ?? {}) as Record<string, unknown>;
  const views: [string, string][] =
    kind === 'ndvi_topdress'
      ? [
          ['ndvi', 'NDVI (filtered)'],
          ['rate', 'Applied rate (kg/ha)'],
        ]
      : [
          ['depth', 'Mean depth (mm)'],
          ['qualified', 'Qualified share (%)'],
        ];
  const alarms = (r.sensor_alarm_records ?? {}) as Record<string, number>;
  const qa = r.qualified_alert as Record<string, unknown> | undefined;
  const all = ((r.depth_table as Record<string, unknown> | undefined)?.all ?? {}) as Record<string, unknown>;
  return (
    <div className="split">
      <aside className="panel">
        <p>
          <a href="#/jobs">← Jobs</a>
        </p>
        <h2>Job #{job.id} report</h2>
        <ErrorBox error={error} />
        {!report && !error && <ReportLoading task={null} onDone={() => undefined} />}
        <Kv
          items={[
            ['Kind', KIND_LABELS[kind] ?? kind, 'report-kind'],
            ['State', job.state, 'report-state'],
            ['Machine', <a href={`#/machines/${job.machine_id}`}>{job.machine_name ?? `#${job.machine_id}`}</a>],
            ['Plan', <a href={`#/plans/${String(job.plan_id)}`}>#{String(job.plan_id)}</a>],
            ['Records', report ? String(r.n_records ?? '–') : '…', 'report-records'],
            ['Sensor held / stopped', `${alarms.sensor_fault ?? 0} / ${alarms.sensor_lost ?? 0} records`, 'report-sensor'],
            ...(kind === 'ndvi_topdress'
              ? ([['Mean shaft-speed error', `${f1(r.mean_relative_error_pct, 2)} % (paper 3.35 %)`, 'report-shaft-error']] as [string, string, string][])
              : ([
                  ['Target depth', `${f1(s.target_depth_mm)} mm`],
                  ['Qualified (all)', `${f1(all.qualified_pct)} %`, 'report-qualified'],
                  [
                    'Low-quality alert',
                    qa ? (qa.triggered ? `yes: worst ${f1(qa.worst_qualified_pct)} % over ${f1(qa.window_m, 0)} m` : `no (worst ${f1(qa.worst_qualified_pct)} %)`) : '–',
                    'report-depth-alert',
                  ],
                ] as [string, string, string][])),
          ]}
        />
        <h3>Table 3 (the paper&apos;s layout)</h3>
        {kind === 'ndvi_topdress' ? <ShaftTable bands={((r.shaft_table as Record<string, unknown> | undefined)?.bands ?? []) as ShaftBand[]} /> : <DepthTable r={r} />}
        <div className="row" role="group">
          {views.map(([k, label]) => (
            <button key={k} data-testid={`view-${k}`} className={view === k ? 'on' : ''} onClick={() => setView(k)}>
              {label}
            </button>
          ))}
        </div>
        <Legend entries={legendEntries(breaks, colors, (v) => (view === 'ndvi' ? v.toFixed(2) : v.toFixed(0)))} title={views.find((v) => v[0] === view)?.[1] ?? ''} testid="report-legend" />
      </aside>
      <MapView name="kind-report" onReady={onReady} />
    </div>
  );
}

function ShaftTable({ bands }: { bands: ShaftBand[] }) {
  const paper = [2.0, 3.6, 3.8, 4.0];
  return (
    <table className="table small" data-testid="shaft-table">
      <thead>
        <tr>
          <th>Speed km/h</th>
          <th>Theoretical r/min</th>
          <th>Monitored r/min</th>
          <th>Rel. error %</th>
          <th>Paper %</th>
        </tr>
      </thead>
      <tbody>
        {bands.map((b, i) => (
          <tr key={b.speed_kmh}>
            <td>{b.speed_kmh}</td>
            <td>{f1(b.theoretical_rpm)}</td>
            <td>{f1(b.monitored_rpm)}</td>
            <td>{f1(b.relative_error_pct, 2)}</td>
            <td className="muted">{paper[i] ?? '–'}</td>
          </tr>
        ))}
      </tbody>
    </table>
  );
}

function DepthTable({ r }: { r: Record<string, unknown> }) {
  const t = (r.depth_table ?? {}) as { bands?: DepthBand[] };
  const paper = r.paper as Record<string, number[]> | undefined;
  return (
    <table className="table small" data-testid="depth-table">
      <thead>
        <tr>
          <th>Speed km/h</th>
          <th>Mean mm</th>
          <th>Qualified %</th>
          <th>SD mm</th>
          <th>CV %</th>
        </tr>
      </thead>
      <tbody>
        {(t.bands ?? []).map((b, i) => (
          <tr key={b.speed_kmh.join('-')}>
            <td>{b.speed_kmh.join('–')}</td>
            <td>
              {f1(b.mean_mm, 2)} <span className="muted">({paper?.mean_mm?.[i] ?? '–'})</span>
            </td>
            <td>
              {f1(b.qualified_pct)} <span className="muted">({paper?.qualified_pct?.[i] ?? '–'})</span>
            </td>
            <td>
              {f1(b.sd_mm, 2)} <span className="muted">({paper?.sd_mm?.[i] ?? '–'})</span>
            </td>
            <td>
              {f1(b.cv_pct, 2)} <span className="muted">({paper?.cv_pct?.[i] ?? '–'})</span>
            </td>
          </tr>
        ))}
      </tbody>
    </table>
  );
}
