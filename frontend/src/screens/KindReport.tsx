import { useMemo, useState } from 'react';
import type { Job } from '../api/client';
import { useAllPlanCells, useField, usePlan } from '../api/hooks';
import { Legend } from '../components/Legend';
import { ReportLoading, useLiveReport } from '../components/ReportLoader';
import { ErrorBox, Kv } from '../components/Status';
import { classColors, legendBreaks, legendEntries, stepExpression } from '../lib/colors';
import { bboxOf } from '../lib/geo';
import { cellValue, KIND_LABELS, type DepthBand, type JobKind, type ShaftBand } from '../lib/jobkinds';
import { outcomeRows, type Outcome } from '../lib/outcome';
import { MapView } from '../map/MapView';
import { CellGrid, FieldBoundary, FitBounds } from '../map/overlays';

/** The legend while no cell has a value (not a made-up 0 – 1 class). */
const NO_VALUES = [{ color: '#dddddd', from: 0, to: 0, label: 'no values yet' }];

const f1 = (v: unknown, d = 1) => (typeof v === 'number' && Number.isFinite(v) ? v.toFixed(d) : '–');

/**
 * Report of a sensor job (seed 000 / 002): the paper's Table 3 and the NDVI / rate / depth maps
 * (the plan's cells as GeoJSON, coloured by the report's per-cell values). Job and report are
 * read again while the job runs (`useLiveReport`).
 */
export function KindReport({ job: initial }: { job: Job }) {
  const kind = initial.kind as JobKind;
  const [view, setView] = useState(kind === 'ndvi_topdress' ? 'ndvi' : 'depth');
  const live = useLiveReport<Record<string, unknown>>(initial.id);
  const job = live.job ?? initial;
  const { report, task } = live;
  const planQ = usePlan(job.plan_id);
  const fieldQ = useField(planQ.data?.field_id);
  const field = fieldQ.data ?? null;
  const cellsQ = useAllPlanCells(job.plan_id);
  const error = live.error ?? planQ.error ?? fieldQ.error ?? cellsQ.error;

  const byseq = useMemo(() => {
    const m = new Map<number, Record<string, unknown>>();
    for (const c of (report?.cells as Record<string, unknown>[] | undefined) ?? []) m.set(Number(c.seq), c);
    return m;
  }, [report]);
  const values = [...byseq.values()].map((c) => cellValue(kind, view, c)).filter((v): v is number => v != null);
  const lo = values.length ? Math.min(...values) : 0;
  const hi = values.length ? Math.max(...values) : 1;
  // never finer than the legend's labels (a constant 30 mm depth is one class "30")
  const decimals = view === 'ndvi' ? 2 : 0;
  const breaks = useMemo(() => legendBreaks(lo, hi, 6, decimals), [lo, hi, decimals]);
  const colors = useMemo(() => classColors(breaks.length - 1), [breaks]);
  const fill = useMemo(() => ['case', ['==', ['get', 'v'], null], '#dddddd', stepExpression('v', breaks, colors)], [breaks, colors]);
  const cells = cellsQ.data;
  const fc = useMemo(
    (): GeoJSON.FeatureCollection | null =>
      cells
        ? {
            type: 'FeatureCollection',
            features: cells.features.map((f) => {
              const c = byseq.get(Number(f.properties?.seq));
              return { ...f, properties: { ...f.properties, v: c ? cellValue(kind, view, c) : null } };
            }),
          }
        : null,
    [cells, byseq, view, kind],
  );

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
        {!report && !error && <ReportLoading task={task} onDone={live.refresh} />}
        <Kv
          items={[
            ...outcomeRows(r.outcome as Outcome | undefined),
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
        <Legend entries={values.length ? legendEntries(breaks, colors, (v) => v.toFixed(decimals)) : NO_VALUES} title={views.find((v) => v[0] === view)?.[1] ?? ''} testid="report-legend" />
      </aside>
      <MapView name="kind-report" fieldId={field?.id}>
        <FitBounds bbox={field ? bboxOf(field) : null} />
        {fc && <CellGrid id="kcells" data={fc} color={fill} />}
        <FieldBoundary data={field} fill={false} />
      </MapView>
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
