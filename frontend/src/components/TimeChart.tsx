import { useEffect, useRef } from 'react';
import uPlot from 'uplot';
import 'uplot/dist/uPlot.min.css';

export interface Series {
  label: string;
  values: (number | null)[];
  color: string;
  dash?: number[];
}

/** Time-series chart (uPlot: fast on thousands of points, tiny bundle). x in unix seconds. */
export function TimeChart({ t, series, title, unit, testid }: { t: number[]; series: Series[]; title: string; unit: string; testid: string }) {
  const ref = useRef<HTMLDivElement>(null);
  const plot = useRef<uPlot | null>(null);
  const key = series.map((s) => s.label).join('|');
  useEffect(() => {
    if (!ref.current) return;
    const opts: uPlot.Options = {
      title,
      width: Math.max(300, ref.current.clientWidth || 600),
      height: 220,
      scales: { x: { time: true } },
      axes: [{}, { label: unit }],
      series: [{}, ...series.map((s) => ({ label: s.label, stroke: s.color, width: 1.5, dash: s.dash, spanGaps: true }))],
    };
    plot.current = new uPlot(opts, [t, ...series.map((s) => s.values)] as uPlot.AlignedData, ref.current);
    return () => {
      plot.current?.destroy();
      plot.current = null;
    };
    // Recreate only when the set of series changes; data updates go through setData below.
    // eslint-disable-next-line react-hooks/exhaustive-deps
  }, [key, title, unit]);
  useEffect(() => {
    plot.current?.setData([t, ...series.map((s) => s.values)] as uPlot.AlignedData);
  }, [t, series]);
  return <div ref={ref} className="chart" data-testid={testid} data-points={t.length} />;
}
