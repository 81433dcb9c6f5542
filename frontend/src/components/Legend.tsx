import type { LegendEntry } from '../lib/colors';

export function Legend({ entries, title, testid = 'legend' }: { entries: LegendEntry[]; title: string; testid?: string }) {
  return (
    <div className="legend" data-testid={testid}>
      <div className="legend-title">{title}</div>
      {entries.map((e, i) => (
        <div key={i} className="legend-row" data-outline={e.outline ? '' : undefined}>
          <span
            className="swatch"
            style={e.outline ? { background: 'transparent', border: `2px dashed ${e.color}`, boxSizing: 'border-box' } : { background: e.color }}
          />
          {e.label}
        </div>
      ))}
    </div>
  );
}

/** Bar per legend class, same colours as the map (plain SVG: no chart library needed for bars). */
export function Histogram({
  counts,
  colors,
  unit = 'cells',
  labels,
  testid = 'histogram',
}: {
  counts: number[];
  colors: string[];
  /** What a bar counts (cells, ha). */
  unit?: string;
  /** Per bar, what it covers (shown on hover). */
  labels?: string[];
  testid?: string;
}) {
  const max = Math.max(1, ...counts);
  const w = 240;
  const h = 80;
  const bw = w / Math.max(1, counts.length);
  return (
    <svg className="histogram" width={w} height={h + 14} data-testid={testid} role="img" aria-label="rate histogram">
      {counts.map((c, i) => {
        const bh = (c / max) * h;
        return (
          <g key={i}>
            <rect x={i * bw + 1} y={h - bh} width={bw - 2} height={bh} fill={colors[i]} stroke="#333" strokeWidth={0.3}>
              <title>
                {labels?.[i] ? `${labels[i]}: ` : ''}
                {c} {unit}
              </title>
            </rect>
            <text x={i * bw + bw / 2} y={h + 11} fontSize={9} textAnchor="middle">
              {c}
            </text>
          </g>
        );
      })}
    </svg>
  );
}
