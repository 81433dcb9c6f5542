import { useState } from 'react';
import { call, client, inline } from '../../api/client';
import { isTask, type TaskView } from '../../lib/tasks';
import { TaskProgress } from '../TaskProgress';
import { formatArea } from '../../lib/units';
import { ErrorBox } from '../Status';
import { Confirm, Skipped, filesBody, fmtDate, num, usePreview, type Done, type Row } from './parts';

/** A TASKDATA set: farms and fields (matched to existing ones), prescriptions, TimeLogs, skips. */
export function IsoxmlPanel({ files, onDone }: { files: File[]; onDone: Done }) {
  const [density, setDensity] = useState('');
  // a confirm runs as a background task: its progress, and how the confirm hears its end
  const [task, setTask] = useState<{ view: TaskView; done: (t: TaskView) => void } | null>(null);
  const query = density ? { density_kg_l: Number(density) } : {};
  const pre = usePreview(
    async () => inline(await call(client.POST('/api/v1/imports/isoxml', { params: { query }, ...filesBody(files) }))),
    [files, density],
  );
  const p = (pre.data?.preview ?? null) as Row | null;
  const needsDensity = !!p?.skipped?.some((s: Row) => s.needs_density) || !!density;
  return (
    <div data-testid="import-isoxml">
      {pre.busy && <p className="muted">Reading the TASKDATA…</p>}
      <ErrorBox error={pre.error} testid="import-preview-error" />
      {p && (
        <>
          <p className="muted">ISO 11783-10 version {p.version}</p>
          <h4>Farms</h4>
          <ul className="list" data-testid="import-farms">
            {p.farms.map((f: Row) => (
              <li key={f.ref}>
                {f.name} {f.match ? <em>— exists already (matched by {f.match.by}), not created again</em> : <em>— new</em>}
              </li>
            ))}
          </ul>
          <h4>Fields ({p.fields.length})</h4>
          <div style={{ overflowX: 'auto' }}>
          <table className="table" data-testid="import-fields">
            <thead>
              <tr>
                <th>Field</th>
                <th>Area</th>
                <th>Holes</th>
                <th>Kept</th>
                <th>Position</th>
                <th />
              </tr>
            </thead>
            <tbody>
              {p.fields.map((f: Row) => (
                <tr key={f.ref} data-testid={`import-field-${f.ref}`}>
                  <td>{f.name}</td>
                  <td>{formatArea(f.area_m2)}</td>
                  <td>{f.holes}</td>
                  <td>{Object.entries(f.features ?? {}).map(([k, n]) => `${n} ${k}`).join(', ') || '–'}</td>
                  <td>{f.centre ? `${num(f.centre[1], 5)}, ${num(f.centre[0], 5)}` : ''}</td>
                  <td>{f.match ? `matches field #${f.match.id} (${f.match.by})` : 'new'}</td>
                </tr>
              ))}
            </tbody>
          </table>
          </div>
          {p.prescriptions.length > 0 && (
            <>
              <h4>Prescriptions</h4>
              <ul className="list" data-testid="import-prescriptions">
                {p.prescriptions.map((r: Row) => (
                  <li key={r.ref}>
                    <strong>{r.name}</strong> ({r.kind}, DDI {r.ddi}, {r.unit}
                    {r.density_kg_l ? ` × ${r.density_kg_l} kg/l` : ''}): {num(r.min_rate_kg_ha)}–{num(r.max_rate_kg_ha)} kg/ha, default{' '}
                    {num(r.default_rate_kg_ha)} kg/ha, covers {num(r.overlap_pct)} % of its field
                    {r.warning && <span className="error"> — {r.warning}</span>}
                    {r.note && <span className="muted"> — {r.note}</span>}
                  </li>
                ))}
              </ul>
            </>
          )}
          {p.timelogs.length > 0 && (
            <>
              <h4>TimeLogs in the set ({p.timelogs.length})</h4>
              <p className="muted">Import them with their prescription: drop the TLG files (or this zip) as TimeLogs.</p>
              <ul className="list" data-testid="import-timelogs">
                {p.timelogs.slice(0, 50).map((t: Row) => (
                  <li key={t.timelog}>
                    {t.timelog} ({t.task_name}): {t.error ?? `${t.records} records, ${fmtDate(t.first_t)} – ${fmtDate(t.last_t)}; ${t.gives}`}
                  </li>
                ))}
              </ul>
            </>
          )}
          <Skipped items={p.skipped} />
          {needsDensity && (
            <label>
              Density of the volume-rate product (kg/l){' '}
              <input data-testid="import-density" type="number" step="0.01" min="0.01" value={density} onChange={(e) => setDensity(e.target.value)} />
            </label>
          )}
          <Confirm
            label={`Import ${p.fields.filter((f: Row) => !f.match).length} new field(s) and ${p.prescriptions.length} prescription(s)`}
            onConfirm={async () => {
              // always in the background: planning a set's grids can take a minute, and the
              // task shows which stage it is at (all or nothing either way)
              const r = await call(
                client.POST('/api/v1/imports/isoxml', {
                  params: { query: { ...query, confirm: pre.data!.sha256, background: true } },
                  ...filesBody(files),
                }),
              );
              let c: Row;
              if (isTask(r)) {
                const t = await new Promise<TaskView>((done) => setTask({ view: r, done }));
                if (t.status !== 'succeeded') throw new Error(t.error ?? `the import was ${t.status}; nothing was stored`);
                c = ((t.result ?? {}) as Row).created ?? {};
              } else {
                c = ((r as Row).created ?? {}) as Row;
              }
              const rx = c.prescriptions?.[0];
              onDone(
                `Imported ${c.fields.length} field(s) (${c.matched_fields.length} matched existing), ${c.prescriptions.length} prescription(s)` +
                  (c.skipped.length ? `; skipped ${c.skipped.map((s: Row) => s.what).join(', ')}` : ''),
                rx ? `#/prescriptions/${rx.id}` : undefined,
              );
            }}
          />
          {task && <TaskProgress task={task.view} onDone={task.done} label="Importing" />}
        </>
      )}
    </div>
  );
}

