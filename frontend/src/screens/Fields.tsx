import { useRef, useState } from 'react';
import { ApiError, call, client, formBody, type Schemas } from '../api/client';
import { qk, useApiMutation, useFarms, useFields, useInvalidate } from '../api/hooks';
import { ImportAssistant } from '../components/ImportAssistant';
import { ErrorBox } from '../components/Status';
import { TaskProgress } from '../components/TaskProgress';
import type { TaskView } from '../lib/tasks';
import { bboxOf } from '../lib/geo';
import { useDebounced } from '../lib/useDebounced';
import { recognise, zipNames } from '../lib/importKind';
import { formatArea } from '../lib/units';
import { MapView } from '../map/MapView';
import { FieldBoundary, FitBounds, Problems } from '../map/overlays';
import { navigate } from '../router';
type FieldCollection = Schemas['FieldCollection'];

const EMPTY: FieldCollection = { type: 'FeatureCollection', features: [], total: 0, limit: 0, offset: 0 };

export function FieldsScreen() {
  const [farmId, setFarmId] = useState<string>('');
  const [q, setQ] = useState('');
  const [batch, setBatch] = useState<TaskView | null>(null);
  const [newFarm, setNewFarm] = useState('');
  const importRef = useRef<HTMLInputElement>(null);
  const [assistant, setAssistant] = useState<File[] | null>(null);
  const [assisted, setAssisted] = useState<{ msg: string; link?: string } | null>(null);
  const farmsQ = useFarms();
  const refresh = useInvalidate();
  const farms = farmsQ.data?.items ?? [];
  const query = { limit: 500, q: useDebounced(q, 200) || undefined, farm_id: farmId ? Number(farmId) : undefined };
  const fieldsQ = useFields(query);
  const fields = fieldsQ.data ?? EMPTY;

  /** One plan per field of the selected farm with the default parameters, in the
   * background (POST /plans/batch); the batch's progress shows below the button. */
  const planFarm = useApiMutation(
    (fid: number) => call(client.POST('/api/v1/plans/batch', { body: { farm_id: fid, params: {} } })),
  );
  const importFile = useApiMutation(
    async (file: File) => {
      const fd = new FormData();
      fd.append('file', file);
      const fid = farmId || (farms[0] ? String(farms[0].id) : '');
      const query = { farm_id: fid ? Number(fid) : undefined };
      return call(client.POST('/api/v1/fields/import', { params: { query }, ...formBody(fd) }));
    },
    { invalidate: () => [qk.fields()] },
  );
  const addFarm = useApiMutation((name: string) => call(client.POST('/api/v1/farms', { body: { name } })), {
    invalidate: () => [qk.farms()],
  });
  const error = importFile.error ?? planFarm.error ?? addFarm.error ?? fieldsQ.error ?? farmsQ.error;
  // An import refused with a location (e.g. a self-intersection) is marked on the map.
  const problem = importFile.error instanceof ApiError ? importFile.error.parsed.location : undefined;
  const imported = importFile.data?.imported;
  const importMsg = importFile.isSuccess
    ? `Imported ${imported || 'the'} field${imported === 1 ? '' : 's'} from ${importFile.variables.name}`
    : '';

  const total = fields.total;
  return (
    <div className="split">
      <aside className="panel">
        <h2>Fields</h2>
        <div className="row">
          <input
            data-testid="field-search"
            placeholder="Search fields…"
            value={q}
            onChange={(e) => setQ(e.target.value)}
          />
          <select data-testid="farm-filter" value={farmId} onChange={(e) => setFarmId(e.target.value)}>
            <option value="">All farms</option>
            {farms.map((f) => (
              <option key={f.id} value={f.id}>
                {f.name}
              </option>
            ))}
          </select>
        </div>
        <div className="row">
          <button data-testid="new-field" data-write="" onClick={() => navigate('/fields/new')}>
            Draw new field
          </button>
          {/* a real button (keyboard reachable, unlike a label around a hidden input) */}
          <button type="button" data-testid="import-button" data-write="" onClick={() => importRef.current?.click()}>
            Import…
          </button>
          <input
            ref={importRef}
            data-testid="import-file"
            data-write=""
            type="file"
            multiple
            hidden
            onChange={async (e) => {
              const list = [...(e.target.files ?? [])];
              e.target.value = '';
              if (!list.length) return;
              // field boundaries import at once (as before); every other format goes
              // through the import assistant's preview
              const described = await Promise.all(
                list.map(async (f) => ({
                  name: f.name,
                  members: f.name.toLowerCase().endsWith('.zip') ? zipNames(await f.arrayBuffer()) : undefined,
                })),
              );
              const kind = recognise(described).kind;
              if (kind === 'fields' && list.length === 1) importFile.mutate(list[0]);
              else {
                setAssisted(null);
                setAssistant(list);
              }
            }}
          />
          <button type="button" data-testid="import-assistant-open" data-write="" onClick={() => setAssistant(assistant ? null : [])}>
            {assistant ? 'Close import' : 'Import farm data…'}
          </button>
        </div>
        {assistant && (
          <ImportAssistant
            key={assistant.map((f) => f.name).join() || 'empty'}
            initialFiles={assistant}
            fields={fields.features}
            farms={farms}
            onDone={(msg, link) => {
              setAssisted({ msg, link });
              setAssistant(null);
              void refresh(qk.fields(), qk.farms());
            }}
          />
        )}
        {assisted && (
          <p className="ok" data-testid="import-assistant-result">
            {assisted.msg}
            {assisted.link && (
              <>
                {' '}
                <a href={assisted.link} data-testid="import-assistant-link">
                  Open
                </a>
              </>
            )}
          </p>
        )}
        {farmId && (
          <div className="row">
            <button
              data-testid="plan-farm"
              data-write=""
              disabled={!!batch && batch.status !== 'succeeded'}
              onClick={() => planFarm.mutate(Number(farmId), { onSuccess: setBatch })}
            >
              Plan every field of this farm
            </button>
          </div>
        )}
        {batch && (
          <TaskProgress
            key={batch.id}
            task={batch}
            label="Planning"
            onDone={(t) => setBatch(t)}
          />
        )}
        {importMsg && (
          <p className="ok" data-testid="import-result">
            {importMsg}
          </p>
        )}
        <ErrorBox error={error} testid="fields-error" />
        <p className="muted" data-testid="field-count">
          {total} field{total === 1 ? '' : 's'}
        </p>
        <ul className="list" data-testid="field-list">
          {fields.features.map((f) => (
            <li key={f.properties.id}>
              <a href={`#/fields/${f.properties.id}`} data-testid={`field-item-${f.properties.id}`}>
                <strong>{f.properties.name}</strong>
              </a>
              <span className="muted">
                {' '}
                {formatArea(f.properties.area_m2 ?? (f.properties.area_ha ?? NaN) * 10_000)}
                {f.properties.crop ? ` · ${f.properties.crop}` : ''}
              </span>
            </li>
          ))}
        </ul>
        <details>
          <summary>Farms</summary>
          <form
            className="row"
            onSubmit={(e) => {
              e.preventDefault();
              addFarm.mutate(newFarm, { onSuccess: () => setNewFarm('') });
            }}
          >
            <input
              data-testid="new-farm-name"
              placeholder="New farm name"
              value={newFarm}
              onChange={(e) => setNewFarm(e.target.value)}
              required
            />
            <button data-testid="new-farm-submit" data-write="">Add farm</button>
          </form>
          <ul className="list">
            {farms.map((f) => (
              <li key={f.id}>{f.name}</li>
            ))}
          </ul>
        </details>
      </aside>
      <MapView name="fields">
        <FieldBoundary id="fields" data={fields} onClick={(id) => navigate(`/fields/${id}`)} />
        <Problems points={[problem]} focus />
        <FitBounds bbox={bboxOf(fields)} />
      </MapView>
    </div>
  );
}
