import { useEffect, useState } from 'react';
import { call, client, type Schemas } from '../api/client';
import { ErrorBox } from './Status';

type Classes = Schemas['LegendClasses'];

/**
 * The version's legend classes as a zones table (class -> ha -> t of product), from the
 * server (every cell, area-weighted). The classes are stored with the version; the class
 * count or the breaks can be changed here (PATCH, the rates stay as they are).
 */
export function ZonesTable(props: {
  rxId: number;
  version: number;
  classes: Classes | null | undefined;
  colors: string[];
  onSaved: () => Promise<void> | void;
}) {
  const { rxId, version, classes, colors, onSaved } = props;
  const [editing, setEditing] = useState(false);
  const [count, setCount] = useState('');
  const [breaks, setBreaks] = useState('');
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<unknown>(null);
  useEffect(() => {
    setCount(String((classes?.breaks_kg_ha.length ?? 7) - 1));
    setBreaks((classes?.breaks_kg_ha ?? []).join(', '));
  }, [classes]);
  const save = async (body: Schemas['VersionPatch']) => {
    setBusy(true);
    setError(null);
    try {
      await call(client.PATCH('/api/v1/prescriptions/{rx_id}/versions/{version}', { params: { path: { rx_id: rxId, version } }, body }));
      await onSaved();
      setEditing(false);
    } catch (e) {
      setError(e);
    } finally {
      setBusy(false);
    }
  };
  if (!classes)
    return (
      <div className="small muted" data-testid="rx-zones">
        No classes stored with this version (made before classes were kept).{' '}
        <button type="button" className="link" data-write="" onClick={() => void save({ class_count: 6 })}>
          Store 6 equal classes
        </button>
        <ErrorBox error={error} testid="rx-classes-error" />
      </div>
    );
  const totals = classes.table.reduce((a, r) => ({ ha: a.ha + r.area_ha, t: a.t + r.product_t }), { ha: 0, t: 0 });
  return (
    <div data-testid="rx-zones">
      <table className="table" data-testid="rx-zones-table">
        <thead>
          <tr>
            <th>Class</th>
            <th>kg/ha</th>
            <th>ha</th>
            <th>t</th>
          </tr>
        </thead>
        <tbody>
          {classes.table.map((r, i) => (
            <tr key={r.class}>
              <td>
                <span className="swatch" style={{ background: colors[i] }} /> {r.class}
              </td>
              <td>
                {r.from_kg_ha.toFixed(0)}–{r.to_kg_ha.toFixed(0)}
              </td>
              <td>{r.area_ha.toFixed(3)}</td>
              <td>{r.product_t.toFixed(3)}</td>
            </tr>
          ))}
          <tr className="total">
            <td colSpan={2}>Total</td>
            <td data-testid="rx-zones-ha">{totals.ha.toFixed(3)}</td>
            <td data-testid="rx-zones-t">{totals.t.toFixed(3)}</td>
          </tr>
        </tbody>
      </table>
      <div className="small muted" data-testid="rx-classes-source">
        Classes: {classes.source}{' '}
        <button type="button" className="link" data-testid="rx-classes-edit" onClick={() => setEditing(!editing)}>
          change
        </button>
      </div>
      {editing && (
        <div className="card" data-testid="rx-classes-form">
          <form
            className="row"
            onSubmit={(e) => {
              e.preventDefault();
              void save({ class_count: Number(count) });
            }}
          >
            <label>
              Equal classes
              <input data-testid="rx-class-count" type="number" min={1} max={20} value={count} onChange={(e) => setCount(e.target.value)} />
            </label>
            <button data-write="" disabled={busy}>
              Apply
            </button>
          </form>
          <form
            className="row"
            onSubmit={(e) => {
              e.preventDefault();
              void save({ breaks_kg_ha: breaks.split(/[,\s]+/).filter(Boolean).map(Number) });
            }}
          >
            <label>
              Breaks (kg/ha)
              <input data-testid="rx-class-breaks" value={breaks} onChange={(e) => setBreaks(e.target.value)} />
            </label>
            <button data-write="" disabled={busy}>
              Apply
            </button>
          </form>
          <ErrorBox error={error} testid="rx-classes-error" />
        </div>
      )}
    </div>
  );
}
