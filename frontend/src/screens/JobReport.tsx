import { useMemo, useState } from 'react';
import { useExportFormats, usePlan, usePrescription, useField, useJob, useJobKinds } from '../api/hooks';
import { ExportButtons } from '../components/ExportButtons';
import { Legend } from '../components/Legend';
import { MapStill, PrintReport, usePrintStill } from '../components/PrintReport';
import { alsoInUnit, nutrientRateText, shownUnit, summaryFractions, unitTotalsText } from '../lib/rxform';
import { ReportLoading, useLiveReport, type AsAppliedReport } from '../components/ReportLoader';
import { ErrorBox, Kv } from '../components/Status';
import { ReplayTrail, TrackReplay, useTrackReplay } from '../components/TrackReplay';
import { ACCURACY_BREAKS, RED_GREEN, classColors, legendEntries, niceBreaks, stepExpression } from '../lib/colors';
import { exportMenu } from '../lib/exportMenu';
import { bboxOf } from '../lib/geo';
import { AREA_BASIS_NOTE, outcomeRows, utcMinute } from '../lib/outcome';
import { formatArea, formatDuration, formatMass, formatPercent } from '../lib/units';
import { MapView } from '../map/MapView';
import { CellGrid, FieldBoundary, FitBounds } from '../map/overlays';
import { absoluteApiUrl } from '../map/setup';
import { KindReport } from './KindReport';

type View = 'applied' | 'accuracy';

const ACTIONS: Record<string, string> = {
  operator_rate_override: 'rate override',
  operator_pause: 'paused',
  operator_section_off: 'section off',
};

/** Where the operator overrode the prescription in the cab, and how long; the alarms acknowledged. */
function operatorText(op: AsAppliedReport['operator']): string {
  const parts = (op?.overrides ?? []).map((o) => `${ACTIONS[o.action] ?? o.action} ${formatDuration(o.seconds)}`);
  const acks = op?.alarm_acks ?? [];
  if (acks.length) parts.push(`${acks.length} alarm ack${acks.length > 1 ? 's' : ''} (${[...new Set(acks.flatMap((a) => a.alarms))].join(', ')})`);
  return parts.length ? parts.join('; ') : 'none';
}
const REPORT_QUERY = { cells: false } as const;

/** As-applied map (job vector tiles), per-cell accuracy, totals, exports, a printable report
 * and a paged replay of the records; a sensor job's report is `KindReport`. */
export function JobReport({ jobId }: { jobId: number }) {
  const jobQ = useJob(jobId);
  const j = jobQ.data;
  const kindsQ = useJobKinds();
  if (jobQ.isPending || kindsQ.isPending) return <p className="muted">Loading…</p>;
  if (j?.kind && kindsQ.data?.kinds[j.kind]?.rates_from === 'sensors') return <KindReport job={j} />;
  return <PrescriptionJobReport jobId={jobId} />;
}

/**
 * The prescription-map (seed 001) job report. Job, report, count and last page of the replay
 * are read again while the job runs (`useLiveReport`); the cell tiles are requested once the
 * report is known (a large job's tiles then read the report task's snapshot instead of
 * computing the report again) and re-requested with each new answer.
 */
function PrescriptionJobReport({ jobId }: { jobId: number }) {
  const [view, setView] = useState<View>('applied');
  const { job, report, task, tick, error, refresh } = useLiveReport<AsAppliedReport>(jobId, REPORT_QUERY);
  const rxQ = usePrescription(job?.prescription_id);
  const rx = rxQ.data ?? null;
  const planQ = usePlan(rx?.plan_id);
  const fieldQ = useField(planQ.data?.field_id);
  const field = fieldQ.data ?? null;
  const replay = useTrackReplay(jobId, tick);
  const printing = usePrintStill();
  const formatsQ = useExportFormats();

  const lo = rx?.summary.rate_min_kg_ha ?? 0;
  const hi = rx?.summary.rate_max_kg_ha ?? 1000;
  const rateBreaks = useMemo(() => niceBreaks(lo, hi === lo ? lo + 1 : hi, 6), [lo, hi]);
  const rateColors = useMemo(() => classColors(rateBreaks.length - 1), [rateBreaks]);
  const accColors = useMemo(() => classColors(ACCURACY_BREAKS.length - 1, RED_GREEN), []);
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
  // Tiles once the view is on the field (or there is no field to fit to) and the report is known.
  const showTiles = report != null && (field != null || fieldQ.isError || planQ.isError || rxQ.isError);

  const r: Partial<AsAppliedReport> = report ?? {};
  // a prescription in another unit than kg/ha: its totals in that unit's count or volume too
  const unitTotals = unitTotalsText(r.unit);
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
        <ErrorBox error={error ?? rxQ.error ?? planQ.error ?? fieldQ.error} />
        {!report && <ReportLoading task={task} onDone={refresh} />}
        <div aria-busy={!report}>
          <Kv
            items={[
              ...outcomeRows(r.outcome),
              ['Worked', report ? `${utcMinute(r.first_t)} – ${utcMinute(r.last_t)}` : '…', 'report-worked'],
              ['State', job?.state ?? '–', 'report-state'],
              ['Machine', job ? <a href={`#/machines/${job.machine_id}`}>{job.machine_name ?? `#${job.machine_id}`}</a> : '–', 'report-machine'],
              [
                'Prescription',
                job ? <a href={`#/prescriptions/${job.prescription_id}`}>#{job.prescription_id} v{job.prescription_version}</a> : '–',
              ],
              ['Product', rx?.product || job?.product || '–', 'report-product'],
              [
                'Mean prescribed rate',
                rx ? nutrientRateText(rx.summary.rate_mean_kg_ha, summaryFractions(rx.summary)) + alsoInUnit(rx.summary.rate_mean_kg_ha, shownUnit(rx)) : '–',
                'report-rate-nutrients',
              ],
              [
                'Flagged cells',
                job?.flagged_cells ? `${String(job.flagged_cells)}${job.flagged_confirmed ? ' (sent on confirmation)' : ''}` : '–',
                'report-flagged',
              ],
              ['Cells applied', report ? `${r.cells_applied ?? '–'} / ${r.cells_planned ?? '–'}` : '…', 'report-cells'],
              ['Coverage', v(cov != null ? formatPercent(cov / 100) : null), 'report-coverage'],
              ['Planned', v(report ? `${formatMass(r.planned_total_kg)} over ${formatArea(r.planned_area_m2)}` : null), 'report-planned'],
              ['Applied', v(formatMass(r.applied_total_kg)), 'report-applied-kg'],
              ...(unitTotals && r.unit ? [[`Totals in ${r.unit.total_unit}`, unitTotals, 'report-unit-totals'] as [string, string, string]] : []),
              ['Applied area', v(formatArea(r.applied_area_m2)), 'report-applied-area'],
              ['Outside cells', v(formatMass(r.applied_outside_cells_kg))],
              ['Mean accuracy', v(acc != null ? `${acc.toFixed(1)} %` : null), 'report-accuracy'],
              ['Worst cell', v(r.min_accuracy_pct != null ? `${r.min_accuracy_pct.toFixed(1)} %` : null)],
              ['Time worked', v(formatDuration(r.time_worked_s))],
              ['Records', v(r.n_records != null ? String(r.n_records) : null), 'report-records'],
              ['Never applied', report && r.never_applied_kg ? `${formatMass(r.never_applied_kg)} in ${notApplied(r)}` : notApplied(r), 'report-not-applied'],
              ['Operator (cab)', report ? operatorText(r.operator) : '…', 'report-operator'],
              ['Field', field ? `${field.properties.name} (${formatArea(r.field_area_m2 || field.properties.area_m2)})` : '–'],
            ]}
          />
        </div>
        <p className="small muted" data-testid="area-basis">
          {AREA_BASIS_NOTE}
        </p>
        <div className="row screen-only" role="group">
          <button data-testid="view-applied" className={view === 'applied' ? 'on' : ''} onClick={() => setView('applied')}>
            As applied
          </button>
          <button data-testid="view-accuracy" className={view === 'accuracy' ? 'on' : ''} onClick={() => setView('accuracy')}>
            Accuracy
          </button>
          <button data-testid="report-print" onClick={printing.print} disabled={!report}>
            Print report
          </button>
        </div>
        <ExportButtons
          path={`/jobs/${jobId}/export`}
          formats={exportMenu(formatsQ.data?.items ?? [], 'job').map((e) => ({
            format: e.query,
            label: e.label,
            fallback: `job${jobId}_as_applied${e.extension}`,
          }))}
        />
        <Legend entries={legend} title={legendTitle} testid="report-legend" />
        <TrackReplay replay={replay} />
      </aside>
      <MapView name="report" fieldId={field?.id}>
        <FitBounds bbox={field ? bboxOf(field) : null} />
        {showTiles && <CellGrid id="job" tiles={tilesUrl(jobId)} color={fill} refreshKey={tick} />}
        <FieldBoundary data={field} fill={false} />
        <ReplayTrail replay={replay} />
        <MapStill still={printing.still} />
      </MapView>
      <PrintReport job={job} field={field} rx={rx} report={report} mapImage={printing.image} legend={legend} legendTitle={legendTitle} />
    </div>
  );
}

function tilesUrl(jobId: number): string {
  return absoluteApiUrl(`/api/v1/tiles/jobs/${jobId}/{z}/{x}/{y}.mvt`);
}
