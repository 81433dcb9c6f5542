import { useEffect, useState } from 'react';
import type { Attention } from '../lib/flags';
import { formatRate } from '../lib/units';

export interface CellInfo {
  seq: number;
  rate: number;
  flags?: string;
  clamped?: boolean;
  /** >1 on overview tiles (cells binned when narrower than ~2 px). */
  nCells: number;
}

/** The clicked cell: its rate and flags, and a new rate for it. */
export function CellEditPanel(props: { cell: CellInfo | null; attention: Attention; onSave: (seq: number, rate: number) => void }) {
  const { cell, attention, onSave } = props;
  const [newRate, setNewRate] = useState('');
  useEffect(() => {
    if (cell) setNewRate(String(Math.round(cell.rate * 10) / 10));
  }, [cell]);
  if (!cell) return <p className="muted">Click a cell to see and edit its rate.</p>;
  return (
    <div className="card" data-testid="cell-panel">
      <div>
        Cell <strong data-testid="cell-seq">{cell.seq}</strong>: <span data-testid="cell-rate">{formatRate(cell.rate)}</span>
        {cell.flags ? <span className={cell.clamped ? 'warn' : 'muted'}> ({cell.flags.replace(/,/g, ', ')})</span> : null}
      </div>
      {cell.flags?.includes('no_data') && (
        <p className="warn small" data-testid="cell-no-data">
          No soil sample near this cell: it has the fallback rate
          {attention.fallbackRate != null ? ` ${formatRate(attention.fallbackRate)}` : ''}.
        </p>
      )}
      {cell.clamped && attention.meter && (
        <p className="warn small" data-testid="cell-out-of-range">
          Outside what the machine meters ({formatRate(attention.meter.rate_min_kg_ha)} at {attention.meter.speed_min_kmh} km/h –{' '}
          {formatRate(attention.meter.rate_max_kg_ha)} at {attention.meter.speed_max_kmh} km/h): stored as asked.
        </p>
      )}
      {cell.nCells > 1 ? (
        <p className="muted">
          {cell.nCells} cells are drawn together at this zoom (mean rate shown); zoom in to edit one cell, or paint a zone.
        </p>
      ) : (
        <form
          className="row"
          onSubmit={(e) => {
            e.preventDefault();
            onSave(cell.seq, Number(newRate));
          }}
        >
          <input data-testid="cell-new-rate" type="number" step="any" value={newRate} onChange={(e) => setNewRate(e.target.value)} />
          <span className="unit">kg/ha</span>
          <button data-testid="cell-save" data-write="">
            Set rate
          </button>
        </form>
      )}
    </div>
  );
}
