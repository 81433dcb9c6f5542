import { useEffect, useRef, useState, type MutableRefObject } from 'react';
import { nutrientRateText, summaryFractions, unitTotalsText } from '../lib/rxform';
import { flushSync } from 'react-dom';
import type * as maplibregl from 'maplibre-gl';
import type { FieldFeature, Job, Prescription } from '../api/client';
import type { LegendEntry } from '../lib/colors';
import { useMap } from '../map/context';
import { AREA_BASIS_NOTE, outcomeRows, utcMinute } from '../lib/outcome';
import { formatArea, formatDuration, formatMass, formatPercent } from '../lib/units';
import { Legend } from './Legend';
import type { AsAppliedReport } from './ReportLoader';

function day(iso: string | null | undefined): string {
  return iso ? new Date(iso).toISOString().replace('T', ' ').slice(0, 16) + ' UTC' : '–';
}

/**
 * A still image of the map for the printed page. The live WebGL canvas does not print
 * reliably (its size is the screen's, it may be blank in the print snapshot); the screen's
 * maps keep their drawing buffer (map/setup.ts), so a synchronous redraw then ``toDataURL``
 * gives the picture on screen.
 */
export function mapSnapshot(map: maplibregl.Map | null): string {
  if (!map) return '';
  try {
    map.redraw();
    return map.getCanvas().toDataURL('image/png');
  } catch {
    return '';
  }
}

/** What takes a still of the map (set by `<MapStill>` inside the MapView); '' before the map is there. */
export type StillRef = MutableRefObject<() => string>;

/**
 * Printing (the screen's button or the browser's own menu): `image` is a still of the map
 * taken just before printing, for `<PrintReport mapImage>`; `still` goes to a `<MapStill>`
 * inside the MapView. `print()` takes the still, lets React put it on the page, then prints.
 */
export function usePrintStill() {
  const [image, setImage] = useState('');
  const still: StillRef = useRef(() => '');
  useEffect(() => {
    const before = () => setImage(still.current());
    window.addEventListener('beforeprint', before);
    return () => window.removeEventListener('beforeprint', before);
  }, []);
  const print = () => {
    flushSync(() => setImage(still.current()));
    window.print();
  };
  return { image, still, print };
}

/** Inside a `<MapView>`: points `still` at a snapshot of that map (see `usePrintStill`). */
export function MapStill({ still }: { still: StillRef }) {
  const map = useMap();
  useEffect(() => {
    still.current = () => mapSnapshot(map);
    return () => {
      still.current = () => '';
    };
  }, [map, still]);
  return null;
}

/**
 * The printable as-applied report (print stylesheet: shown only in print media, the
 * screen's controls hidden): field, dates, machine, product, totals, the map and its legend.
 */
export function PrintReport(props: {
  job: Job | null;
  field: FieldFeature | null;
  rx: Prescription | null;
  report: AsAppliedReport | null;
  mapImage: string;
  legend: LegendEntry[];
  legendTitle: string;
}) {
  const { job, field, rx, report: r, mapImage, legend, legendTitle } = props;
  const rows: [string, string, string][] = [
    ...outcomeRows(r?.outcome).map(([k, v, tid]): [string, string, string] => [k, v, tid.replace('report-', 'print-')]),
    ['Field', field ? `${field.properties.name} (${formatArea(r?.field_area_m2 || field.properties.area_m2)})` : job?.field_name ?? '–', 'print-field'],
    // the work itself (its first and last record), not when the job was sent or closed
    ['Date', r ? `${utcMinute(r.first_t)} – ${utcMinute(r.last_t)}` : `${day(job?.started_at)} – ${day(job?.ended_at)}`, 'print-date'],
    ['Machine', job ? `${job.machine_name ?? `#${job.machine_id}`} (${r?.implement_width_m ?? '–'} m)` : '–', 'print-machine'],
    [
      'Product',
      `${rx?.product || job?.product || '–'}${job?.prescription_id != null ? ` · prescription #${job.prescription_id} v${job.prescription_version ?? '?'}` : ''}`,
      'print-product',
    ],
    ['Mean prescribed rate', rx ? nutrientRateText(rx.summary.rate_mean_kg_ha, summaryFractions(rx.summary)) : '–', 'print-rate-nutrients'],
    ['Job', job ? `#${job.id} ${job.name} (${job.state})` : '–', 'print-job'],
  ];
  const totals: [string, string][] = r
    ? [
        ['Planned', `${formatMass(r.planned_total_kg)} over ${formatArea(r.planned_area_m2)}`],
        ['Applied', `${formatMass(r.applied_total_kg)} over ${formatArea(r.applied_area_m2)}`],
        ...(r.unit && unitTotalsText(r.unit) ? ([[`Totals in ${r.unit.total_unit}`, unitTotalsText(r.unit) ?? '']] as [string, string][]) : []),
        ['Never applied', formatMass(r.never_applied_kg)],
        ['Outside cells', formatMass(r.applied_outside_cells_kg)],
        ['Cells applied', `${r.cells_applied} / ${r.cells_planned}`],
        ['Coverage', formatPercent(r.coverage_pct / 100)],
        ['Mean accuracy', r.mean_accuracy_pct != null ? `${r.mean_accuracy_pct.toFixed(1)} %` : '–'],
        ['Worst cell', r.min_accuracy_pct != null ? `${r.min_accuracy_pct.toFixed(1)} %` : '–'],
        ['Time worked', formatDuration(r.time_worked_s)],
        ['Records', r.n_records.toLocaleString()],
      ]
    : [];
  return (
    <section className="print-report print-only" data-testid="print-report">
      <h1>As-applied report</h1>
      <table className="print-facts">
        <tbody>
          {rows.map(([k, v, tid]) => (
            <tr key={k}>
              <th>{k}</th>
              <td data-testid={tid}>{v}</td>
            </tr>
          ))}
        </tbody>
      </table>
      <h2>Totals</h2>
      <table className="print-totals" data-testid="print-totals">
        <tbody>
          {totals.map(([k, v]) => (
            <tr key={k}>
              <th>{k}</th>
              <td>{v}</td>
            </tr>
          ))}
        </tbody>
      </table>
      <div className="print-map-row">
        {mapImage ? <img className="print-map" data-testid="print-map" src={mapImage} alt="As-applied map" /> : <p>(map not drawn yet)</p>}
        <Legend entries={legend} title={legendTitle} testid="print-legend" />
      </div>
      <p className="small muted">
        Accuracy per cell θ = (1 − |M1 − M2| / M1) × 100 % (seed 001 eq. 18). {AREA_BASIS_NOTE} Printed {new Date().toISOString().slice(0, 10)}.
      </p>
    </section>
  );
}
