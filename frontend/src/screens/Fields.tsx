import { useCallback, useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { ApiError, call, client, formBody, type Farm, type Schemas } from '../api/client';
import { ErrorBox } from '../components/Status';
import { TaskProgress } from '../components/TaskProgress';
import type { TaskView } from '../lib/tasks';
import { asGeoJSON, bboxOf } from '../lib/geo';
import { formatArea } from '../lib/units';
import { MapView } from '../map/MapView';
import { fitTo, setGeoJSON } from '../map/setup';
import { navigate } from '../router';
type FieldCollection = Schemas['FieldCollection'];

const EMPTY: FieldCollection = { type: 'FeatureCollection', features: [], total: 0, limit: 0, offset: 0 };

export function FieldsScreen() {
  const [farms, setFarms] = useState<Farm[]>([]);
  const [farmId, setFarmId] = useState<string>('');
  const [q, setQ] = useState('');
  const [fields, setFields] = useState<FieldCollection>(EMPTY);
  const [error, setError] = useState<unknown>(null);
  const importRef = useRef<HTMLInputElement>(null);
  const [importMsg, setImportMsg] = useState('');
  const [batch, setBatch] = useState<TaskView | null>(null);
  const [newFarm, setNewFarm] = useState('');
  const mapRef = useRef<maplibregl.Map | null>(null);
  const fitted = useRef(false);

  const loadFarms = useCallback(async () => {
    try {
      setFarms((await call(client.GET('/api/v1/farms'))).items);
    } catch (e) {
      setError(e);
    }
  }, []);

  const loadFields = useCallback(async () => {
    const query = { limit: 500, q: q || undefined, farm_id: farmId ? Number(farmId) : undefined };
    try {
      setFields(await call(client.GET('/api/v1/fields', { params: { query } })));
      setError(null);
    } catch (e) {
      setError(e);
    }
  }, [q, farmId]);

  useEffect(() => {
    void loadFarms();
  }, [loadFarms]);
  useEffect(() => {
    const t = setTimeout(() => void loadFields(), 200);
    return () => clearTimeout(t);
  }, [loadFields]);

  // An import refused with a location (e.g. a self-intersection) is marked on the map.
  const problem = error instanceof ApiError ? error.parsed.location : undefined;
  useEffect(() => {
    const map = mapRef.current;
    if (!map || !map.getSource('problems')) return;
    setGeoJSON(map, 'problems', {
      type: 'FeatureCollection',
      features: problem ? [{ type: 'Feature', properties: {}, geometry: { type: 'Point', coordinates: problem } }] : [],
    });
    if (problem) map.jumpTo({ center: problem, zoom: Math.max(map.getZoom(), 15) });
  }, [problem?.[0], problem?.[1]]); // eslint-disable-line react-hooks/exhaustive-deps

  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    setGeoJSON(map, 'fields', asGeoJSON(fields));
    if (!fitted.current || q || farmId) {
      fitTo(map, bboxOf(fields));
      if (fields.features.length) fitted.current = true;
    }
  }, [fields, q, farmId]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'fields', asGeoJSON(fields));
    map.addLayer({
      id: 'fields-fill',
      type: 'fill',
      source: 'fields',
      paint: { 'fill-color': '#4c9a2a', 'fill-opacity': 0.35 },
    });
    map.addLayer({
      id: 'fields-line',
      type: 'line',
      source: 'fields',
      paint: { 'line-color': '#2d5e16', 'line-width': 2 },
    });
    setGeoJSON(map, 'problems', { type: 'FeatureCollection', features: [] });
    map.addLayer({
      id: 'problems',
      type: 'circle',
      source: 'problems',
      paint: { 'circle-radius': 14, 'circle-color': 'rgba(215, 38, 61, 0.35)', 'circle-stroke-color': '#d7263d', 'circle-stroke-width': 3 },
    });
    map.on('click', 'fields-fill', (e) => {
      const f = e.features?.[0];
      const id = f?.properties?.id ?? f?.id;
      if (id != null) navigate(`/fields/${id}`);
    });
    map.on('mouseenter', 'fields-fill', () => (map.getCanvas().style.cursor = 'pointer'));
    map.on('mouseleave', 'fields-fill', () => (map.getCanvas().style.cursor = ''));
    fitTo(map, bboxOf(fields));
  };

  /** One plan per field of the selected farm with the default parameters, in the
   * background (POST /plans/batch); the batch's progress shows below the button. */
  const planFarm = async () => {
    setError(null);
    try {
      setBatch(await call(client.POST('/api/v1/plans/batch', { body: { farm_id: Number(farmId), params: {} } })));
    } catch (e) {
      setError(e);
    }
  };

  const onImport = async (file: File) => {
    setImportMsg('');
    setError(null);
    const fd = new FormData();
    fd.append('file', file);
    const fid = farmId || (farms[0] ? String(farms[0].id) : '');
    try {
      const query = { farm_id: fid ? Number(fid) : undefined };
      const r = await call(client.POST('/api/v1/fields/import', { params: { query }, ...formBody(fd) }));
      const n = r.imported;
      setImportMsg(`Imported ${n || 'the'} field${n === 1 ? '' : 's'} from ${file.name}`);
      await loadFields();
    } catch (e) {
      setError(e);
    }
  };

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
            accept=".geojson,.json,.kml,.zip"
            hidden
            onChange={(e) => {
              const f = e.target.files?.[0];
              if (f) void onImport(f);
              e.target.value = '';
            }}
          />
        </div>
        {farmId && (
          <div className="row">
            <button
              data-testid="plan-farm"
              data-write=""
              disabled={!!batch && batch.status !== 'succeeded'}
              onClick={() => void planFarm()}
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
            onSubmit={async (e) => {
              e.preventDefault();
              try {
                await call(client.POST('/api/v1/farms', { body: { name: newFarm } }));
                setNewFarm('');
                await loadFarms();
              } catch (err) {
                setError(err);
              }
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
      <MapView name="fields" onReady={onReady} />
    </div>
  );
}
