import { useMemo, useState } from 'react';
import type { Job } from '../api/client';
import { useAllPlanCells, useField, useJobKinds, usePlan } from '../api/hooks';
import { Legend } from '../components/Legend';
import { ReportLoading, useLiveReport } from '../components/ReportLoader';
import { ErrorBox, Kv } from '../components/Status';
import { classColors, legendBreaks, legendEntries, stepExpression } from '../lib/colors';
import { bboxOf } from '../lib/geo';
import { cellValue, kindUi } from '../kinds';
import { kindLabel } from '../lib/jobkinds';
import { outcomeRows, type Outcome } from '../lib/outcome';
import { MapView } from '../map/MapView';
import { CellGrid, FieldBoundary, FitBounds } from '../map/overlays';

/** The legend while no cell has a value (not a made-up 0 – 1 class). */
const NO_VALUES = [{ color: '#dddddd', from: 0, to: 0, label: 'no values yet' }];

/**
 * Report of a sensor job: the kind's figures and its paper's Table 3 (src/kinds/), and its maps
 * (the plan's cells as GeoJSON, coloured by the report's per-cell values in the kind's views,
 * e.g. NDVI / rate or depth / qualified share). Job and report are read again while the job
 * runs (`useLiveReport`).
 */
export function KindReport({ job: initial }: { job: Job }) {
  const kind = initial.kind ?? '';
  const ui = kindUi(kind);
  const kinds = useJobKinds().data?.kinds;
  const views = ui.views ?? [];
  const [view, setView] = useState(views[0]?.key ?? '');
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
  const values = [...byseq.values()].map((c) => cellValue(ui, view, c)).filter((v): v is number => v != null);
  const lo = values.length ? Math.min(...values) : 0;
  const hi = values.length ? Math.max(...values) : 1;
  // never finer than the legend's labels (a constant 30 mm depth is one class "30")
  const decimals = views.find((v) => v.key === view)?.decimals ?? 0;
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
              return { ...f, properties: { ...f.properties, v: c ? cellValue(ui, view, c) : null } };
            }),
          }
        : null,
    [cells, byseq, view, ui],
  );

  const r = report ?? {};
  const s = (job.settings ?? {}) as Record<string, unknown>;
  const alarms = (r.sensor_alarm_records ?? {}) as Record<string, number>;
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
            ['Kind', kindLabel(kinds, kind), 'report-kind'],
            ['State', job.state, 'report-state'],
            ['Machine', <a href={`#/machines/${job.machine_id}`}>{job.machine_name ?? `#${job.machine_id}`}</a>],
            ['Plan', <a href={`#/plans/${String(job.plan_id)}`}>#{String(job.plan_id)}</a>],
            ['Records', report ? String(r.n_records ?? '–') : '…', 'report-records'],
            ['Sensor held / stopped', `${alarms.sensor_fault ?? 0} / ${alarms.sensor_lost ?? 0} records`, 'report-sensor'],
            ...(ui.reportRows?.(r, s) ?? []),
          ]}
        />
        {ui.reportTable && <h3>Table 3 (the paper&apos;s layout)</h3>}
        {ui.reportTable?.(r)}
        <div className="row" role="group">
          {views.map((v) => (
            <button key={v.key} data-testid={`view-${v.key}`} className={view === v.key ? 'on' : ''} onClick={() => setView(v.key)}>
              {v.label}
            </button>
          ))}
        </div>
        <Legend entries={values.length ? legendEntries(breaks, colors, (v) => v.toFixed(decimals)) : NO_VALUES} title={views.find((v) => v.key === view)?.label ?? ''} testid="report-legend" />
      </aside>
      <MapView name="kind-report" fieldId={field?.id}>
        <FitBounds bbox={field ? bboxOf(field) : null} />
        {fc && <CellGrid id="kcells" data={fc} color={fill} />}
        <FieldBoundary data={field} fill={false} />
      </MapView>
    </div>
  );
}
