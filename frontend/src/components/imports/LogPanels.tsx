import { useEffect, useState } from 'react';
import { call, client } from '../../api/client';
import { ErrorBox } from '../Status';
import { Confirm, filesBody, fmtDate, num, usePreview, type Done, type Farm, type Rx } from './parts';

/** As-applied data (TimeLogs, tables) on a prescription, and plain field boundaries. */
function RxPicker({ rxs, value, onChange }: { rxs: Rx[]; value: string; onChange: (v: string) => void }) {
  return (
    <label>
      As applied on prescription{' '}
      <select data-testid="import-target-rx" value={value} onChange={(e) => onChange(e.target.value)}>
        <option value="">–</option>
        {rxs.map((r) => (
          <option key={r.id} value={r.id}>
            #{r.id} {r.name}
          </option>
        ))}
      </select>
    </label>
  );
}

export function TimelogPanel({ files, rxs, onDone }: { files: File[]; rxs: Rx[]; onDone: Done }) {
  const [rxId, setRxId] = useState(rxs.length ? String(rxs[rxs.length - 1].id) : '');
  const [width, setWidth] = useState('');
  const query = { prescription_id: Number(rxId), ...(width ? { width_m: Number(width) } : {}) };
  const pre = usePreview(
    rxId ? () => call(client.POST('/api/v1/imports/timelog', { params: { query }, ...filesBody(files) })) : null,
    [files, rxId, width],
  );
  const d = pre.data;
  return (
    <div data-testid="import-timelog">
      <RxPicker rxs={rxs} value={rxId} onChange={setRxId} />
      <ErrorBox error={pre.error} testid="import-preview-error" />
      {d && (
        <>
          <div style={{ overflowX: 'auto' }}>
          <table className="table" data-testid="import-logs">
            <thead>
              <tr>
                <th>Log</th>
                <th>Records</th>
                <th>From – to (UTC)</th>
                <th>On the field</th>
                <th>Gives</th>
              </tr>
            </thead>
            <tbody>
              {d.timelogs.map((t) => (
                <tr key={t.timelog}>
                  <td>{t.timelog}</td>
                  <td>
                    {t.records} ({t.with_position} with position)
                  </td>
                  <td>
                    {fmtDate(t.first_t)} – {fmtDate(t.last_t)}
                  </td>
                  <td>{t.placement ? `${t.placement.on_field} records` : '–'}</td>
                  <td>{t.gives}</td>
                </tr>
              ))}
            </tbody>
          </table>
          </div>
          {(d.refused ?? []).map((r) => (
            <p key={r} className="error" data-testid="import-refused">
              {r}
            </p>
          ))}
          <label>
            Working width (m){' '}
            <input
              data-testid="import-width"
              type="number"
              step="0.1"
              placeholder={d.width_m != null ? String(d.width_m) : 'not in the logs'}
              value={width}
              onChange={(e) => setWidth(e.target.value)}
            />
          </label>
          <Confirm
            label="Import as a completed job"
            disabled={(d.refused ?? []).length > 0 || d.width_m == null}
            onConfirm={async () => {
              const r = await call(client.POST('/api/v1/imports/timelog', { params: { query: { ...query, confirm: d.sha256 } }, ...filesBody(files) }));
              onDone(`Imported ${r.created?.records} records as job ${r.created?.job_id}`, `#/jobs/${r.created?.job_id}`);
            }}
          />
        </>
      )}
    </div>
  );
}

const TABLE_KEYS = ['rate_column', 'lon_column', 'lat_column', 'speed_column', 'time_column', 'target_column', 'work_state_column'] as const;

export function AsAppliedPanel({ file, rxs, onDone }: { file: File; rxs: Rx[]; onDone: Done }) {
  const [rxId, setRxId] = useState(rxs.length ? String(rxs[rxs.length - 1].id) : '');
  const [map, setMap] = useState<Record<string, string>>({});
  const [unit, setUnit] = useState('kg/ha');
  const [width, setWidth] = useState('');
  const mapped = Object.fromEntries(Object.entries(map).filter(([, v]) => v));
  const query = { prescription_id: Number(rxId), unit, ...mapped, ...(width ? { width_m: Number(width) } : {}) };
  const pre = usePreview(
    rxId ? () => call(client.POST('/api/v1/imports/as-applied-table', { params: { query }, ...filesBody([file], 'file') })) : null,
    [file, rxId, JSON.stringify(map), unit, width],
  );
  const d = pre.data;
  useEffect(() => {
    if (d && !Object.keys(map).length) {
      const s = Object.fromEntries(TABLE_KEYS.map((k) => [k, (d.suggested as Record<string, string | null>)[k] ?? '']));
      setMap(s);
    }
  }, [d, map]);
  return (
    <div data-testid="import-as-applied">
      <RxPicker rxs={rxs} value={rxId} onChange={setRxId} />
      <ErrorBox error={pre.error} testid="import-preview-error" />
      {d && (
        <>
          <p className="muted">
            {d.rows} rows, columns {d.columns.join(', ')}
          </p>
          <div className="row">
            {TABLE_KEYS.map((k) => (
              <label key={k}>
                {k.replace('_column', '').replace('_', ' ')}{' '}
                <select data-testid={`import-map-${k}`} value={map[k] ?? ''} onChange={(e) => setMap({ ...map, [k]: e.target.value })}>
                  <option value="">–</option>
                  {d.columns.map((c) => (
                    <option key={c}>{c}</option>
                  ))}
                </select>
              </label>
            ))}
            <label>
              Rate unit <input data-testid="import-unit" value={unit} onChange={(e) => setUnit(e.target.value)} size={8} />
            </label>
            <label>
              Working width (m) <input data-testid="import-width" type="number" step="0.1" value={width} onChange={(e) => setWidth(e.target.value)} />
            </label>
          </div>
          {d.mapping && (
            <p data-testid="import-mapping">
              {d.mapping.records} records, mean applied {num(d.mapping.mean_applied_rate_kg_ha)} kg/ha at {num(d.mapping.mean_speed_m_s, 2)} m/s; times{' '}
              {d.mapping.times}
            </p>
          )}
          <Confirm
            label="Import as a completed job"
            disabled={!d.mapping || !width}
            onConfirm={async () => {
              const r = await call(
                client.POST('/api/v1/imports/as-applied-table', { params: { query: { ...query, confirm: d.sha256 } }, ...filesBody([file], 'file') }),
              );
              onDone(`Imported ${r.created?.records} records as job ${r.created?.job_id}`, `#/jobs/${r.created?.job_id}`);
            }}
          />
        </>
      )}
    </div>
  );
}

export function FieldsPanel({ file, farms, onDone }: { file: File; farms: Farm[]; onDone: Done }) {
  const [farmId, setFarmId] = useState(farms[0] ? String(farms[0].id) : '');
  return (
    <div data-testid="import-fields-file">
      <label>
        Into farm{' '}
        <select data-testid="import-target-farm" value={farmId} onChange={(e) => setFarmId(e.target.value)}>
          <option value="">(no farm)</option>
          {farms.map((f) => (
            <option key={f.id} value={f.id}>
              {f.name}
            </option>
          ))}
        </select>
      </label>
      <Confirm
        label="Import fields"
        onConfirm={async () => {
          const r = await call(
            client.POST('/api/v1/fields/import', { params: { query: { farm_id: farmId ? Number(farmId) : undefined } }, ...filesBody([file], 'file') }),
          );
          onDone(`Imported ${r.imported} field${r.imported === 1 ? '' : 's'} from ${file.name}`);
        }}
      />
    </div>
  );
}

