/**
 * Seed 002's depth-controlled seeding: the GB/T 20865 band under its form, and its report's
 * figures (qualified share, low-quality alert, Table 3) and map views (depth, qualified share).
 */
import { f1, type KindUi } from './types';

/** GB/T 20865 qualified band: +-10 mm at a target of 30 mm or more, +-5 mm below. */
export function qualifiedBand(targetMm: number): [number, number] {
  const tol = targetMm >= 30 ? 10 : 5;
  return [targetMm - tol, targetMm + tol];
}

export interface DepthBand {
  speed_kmh: [number, number];
  n: number;
  mean_mm?: number;
  qualified_pct?: number;
  sd_mm?: number;
  cv_pct?: number;
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

export const ui: KindUi = {
  name: 'seeding_depth',
  formNote: (values) => {
    const target = Number(values.target_depth_mm ?? 30);
    const band = qualifiedBand(Number.isFinite(target) ? target : 30);
    return (
      <p className="muted small" data-testid="depth-band">
        Qualified (GB/T 20865): {band[0]}–{band[1]} mm.
      </p>
    );
  },
  views: [
    { key: 'depth', label: 'Mean depth (mm)', column: 'depth_mm', decimals: 0 },
    { key: 'qualified', label: 'Qualified share (%)', column: 'qualified_pct', decimals: 0 },
  ],
  reportRows: (r, s) => {
    const qa = r.qualified_alert as Record<string, unknown> | undefined;
    const all = ((r.depth_table as Record<string, unknown> | undefined)?.all ?? {}) as Record<string, unknown>;
    return [
      ['Target depth', `${f1(s.target_depth_mm)} mm`],
      ['Qualified (all)', `${f1(all.qualified_pct)} %`, 'report-qualified'],
      [
        'Low-quality alert',
        qa ? (qa.triggered ? `yes: worst ${f1(qa.worst_qualified_pct)} % over ${f1(qa.window_m, 0)} m` : `no (worst ${f1(qa.worst_qualified_pct)} %)`) : '–',
        'report-depth-alert',
      ],
    ];
  },
  reportTable: (r) => <DepthTable r={r} />,
};
