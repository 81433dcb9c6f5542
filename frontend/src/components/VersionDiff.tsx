import { useEffect, useState } from 'react';
import { call, client, type Schemas } from '../api/client';
import { formatProduct } from '../lib/rxform';
import { formatRate } from '../lib/units';
import { ErrorBox, Kv } from './Status';

const signed = (x: number, text: string) => `${x > 0 ? '+' : x < 0 ? '−' : '±'}${text}`;

/** Compare two versions (server diff: cells and area changed, product and cost delta). */
export function VersionDiff({ rxId, versions, shown }: { rxId: number; versions: number[]; shown: number | null }) {
  const [from, setFrom] = useState<number | null>(null);
  const [to, setTo] = useState<number | null>(null);
  const [diff, setDiff] = useState<Schemas['VersionDiff'] | null>(null);
  const [error, setError] = useState<unknown>(null);
  // Default: the version on screen against the one before it.
  useEffect(() => {
    if (shown == null) return;
    const i = versions.indexOf(shown);
    setTo(shown);
    setFrom(i > 0 ? versions[i - 1] : (versions.find((v) => v !== shown) ?? shown));
    setDiff(null);
  }, [shown, versions]);
  if (versions.length < 2) return <p className="muted small">One version: nothing to compare yet.</p>;
  const pick = (value: number | null, set: (v: number) => void, tid: string) => (
    <select data-testid={tid} value={value ?? ''} onChange={(e) => set(Number(e.target.value))}>
      {versions.map((v) => (
        <option key={v} value={v}>
          v{v}
        </option>
      ))}
    </select>
  );
  return (
    <div data-testid="rx-diff">
      <form
        className="row"
        onSubmit={async (e) => {
          e.preventDefault();
          if (from == null || to == null) return;
          setError(null);
          try {
            setDiff(
              await call(
                client.GET('/api/v1/prescriptions/{rx_id}/diff', { params: { path: { rx_id: rxId }, query: { from, to } } }),
              ),
            );
          } catch (err) {
            setError(err);
          }
        }}
      >
        {pick(from, setFrom, 'rx-diff-from')} → {pick(to, setTo, 'rx-diff-to')}
        <button data-testid="rx-diff-run">Compare</button>
      </form>
      <ErrorBox error={error} testid="rx-diff-error" />
      {diff && (
        <div data-testid="rx-diff-result">
          <Kv
            items={[
              ['Versions', `v${diff.from_version} → v${diff.to_version}`],
              ['Cells changed', String(diff.cells_changed), 'rx-diff-cells'],
              ['Area changed', `${diff.area_changed_ha.toFixed(3)} ha`, 'rx-diff-area'],
              ['Product', signed(diff.product_kg_delta, formatProduct(Math.abs(diff.product_kg_delta))), 'rx-diff-product'],
              ['Mean rate', diff.rate_mean_delta_kg_ha == null ? '–' : signed(diff.rate_mean_delta_kg_ha, formatRate(Math.abs(diff.rate_mean_delta_kg_ha))), 'rx-diff-mean'],
              ['Cost', diff.cost_delta == null ? '– (no price)' : signed(diff.cost_delta, Math.abs(diff.cost_delta).toFixed(2)), 'rx-diff-cost'],
              ['Largest change', `+${formatRate(diff.max_increase_kg_ha)} / −${formatRate(diff.max_decrease_kg_ha)}`],
            ]}
          />
          {diff.cells_changed > 0 && (
            <div className="small muted">
              Cells: {diff.seq.slice(0, 30).join(', ')}
              {diff.cells_changed > 30 ? ` … (${diff.cells_changed - 30} more)` : ''}
            </div>
          )}
        </div>
      )}
    </div>
  );
}
