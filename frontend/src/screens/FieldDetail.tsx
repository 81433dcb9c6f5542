import { useCallback, useEffect, useRef, useState } from 'react';
import * as maplibregl from 'maplibre-gl';
import { ApiError, call, client, formBody, type FieldFeature, type Plan, type Schemas } from '../api/client';
import { ErrorBox, Kv } from '../components/Status';
import { Legend } from '../components/Legend';
import { classColors, legendEntries, niceBreaks, stepExpression } from '../lib/colors';
import { asGeoJSON, bboxOf } from '../lib/geo';
import { formatArea } from '../lib/units';
import { MapView } from '../map/MapView';
import { fitTo, setGeoJSON } from '../map/setup';
import { navigate } from '../router';
import { PlanForm } from './PlanForm';

type SoilFC = Schemas['SampleCollection'];
type SoilImportRow = Schemas['SoilImportRow'];
type OutsideRow = Schemas['OutsideRow'];

const SKIP_KEYS = new Set([
  'id',
  'field_id',
  'geometry',
  'lon',
  'lat',
  'created_at',
  'organisation_id',
  'import_batch',
  'import_id',
]);

/** One field: boundary, soil samples, plans; soil CSV upload with per-row errors. */
export function FieldDetail({ fieldId }: { fieldId: number }) {
  const [field, setField] = useState<FieldFeature | null>(null);
  const [plans, setPlans] = useState<Plan[]>([]);
  const [soil, setSoil] = useState<SoilFC | null>(null);
  const [error, setError] = useState<unknown>(null);
  const [soilError, setSoilError] = useState<unknown>(null);
  const [soilMsg, setSoilMsg] = useState('');
  const [skipBad, setSkipBad] = useState(false);
  const [includeOutside, setIncludeOutside] = useState(false);
  const [outside, setOutside] = useState<OutsideRow[]>([]);
  const [imports, setImports] = useState<SoilImportRow[]>([]);
  const [colorKey, setColorKey] = useState('');
  const mapRef = useRef<maplibregl.Map | null>(null);

  const loadSoil = useCallback(async () => {
    try {
      const path = { field_id: fieldId };
      setSoil(await call(client.GET('/api/v1/fields/{field_id}/soil-samples', { params: { path } })));
      setImports((await call(client.GET('/api/v1/fields/{field_id}/soil-imports', { params: { path } }))).items);
    } catch (e) {
      setSoilError(e);
    }
  }, [fieldId]);

  useEffect(() => {
    const path = { field_id: fieldId };
    call(client.GET('/api/v1/fields/{field_id}', { params: { path } }))
      .then(setField)
      .catch(setError);
    call(client.GET('/api/v1/fields/{field_id}/plans', { params: { path } }))
      .then((r) => setPlans(r.items))
      .catch(setError);
    void loadSoil();
  }, [fieldId, loadSoil]);

  useEffect(() => {
    const map = mapRef.current;
    if (!map || !field) return;
    setGeoJSON(map, 'field', asGeoJSON(field));
    fitTo(map, bboxOf(field));
  }, [field]);
  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    setGeoJSON(map, 'soil', soil ? asGeoJSON(soil) : { type: 'FeatureCollection', features: [] });
  }, [soil]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'field', field ? asGeoJSON(field) : { type: 'FeatureCollection', features: [] });
    map.addLayer({ id: 'field-fill', type: 'fill', source: 'field', paint: { 'fill-color': '#4c9a2a', 'fill-opacity': 0.25 } });
    map.addLayer({ id: 'field-line', type: 'line', source: 'field', paint: { 'line-color': '#2d5e16', 'line-width': 2 } });
    setGeoJSON(map, 'soil', soil ? asGeoJSON(soil) : { type: 'FeatureCollection', features: [] });
    map.addLayer({
      id: 'soil',
      type: 'circle',
      source: 'soil',
      paint: { 'circle-radius': 7, 'circle-color': '#8b4513', 'circle-stroke-color': '#222', 'circle-stroke-width': 1.5 },
    });
    map.on('click', 'soil', (e) => {
      const f = e.features?.[0];
      if (!f) return;
      const rows = Object.entries(f.properties ?? {})
        .filter(([k]) => !SKIP_KEYS.has(k))
        .map(([k, v]) => `<tr><th>${k}</th><td>${String(v)}</td></tr>`)
        .join('');
      new maplibregl.Popup().setLngLat(e.lngLat).setHTML(`<table class="popup">${rows}</table>`).addTo(map);
    });
    if (field) fitTo(map, bboxOf(field));
  };

  const uploadSoil = async (file: File) => {
    setSoilError(null);
    setSoilMsg('');
    setOutside([]);
    const fd = new FormData();
    fd.append('file', file);
    const query = { skip_bad_rows: skipBad || undefined, include_outside: includeOutside || undefined };
    try {
      const r = await call(
        client.POST('/api/v1/fields/{field_id}/soil-samples', {
          params: { path: { field_id: fieldId }, query },
          ...formBody(fd),
        }),
      );
      const far = r.outside;
      setOutside(far);
      setSoilMsg(
        `Uploaded ${file.name}: ${r.imported} samples${r.skipped ? `, ${r.skipped} rows skipped` : ''}${
          far.length ? `, ${far.length} outside the field ${r.outside_stored ? '(stored as asked)' : '(not stored)'}` : ''
        }`,
      );
      await loadSoil();
    } catch (e) {
      const body = e instanceof ApiError ? (e.body as Schemas['ErrorOut'] | null) : null;
      if (body && Array.isArray(body.outside)) setOutside(body.outside as OutsideRow[]);
      setSoilError(e);
    }
  };

  const remove = async (del: () => Promise<Schemas['Deleted']>, what: string) => {
    if (!confirm(`Delete ${what}?`)) return;
    setSoilError(null);
    try {
      const r = await del();
      setSoilMsg(`Deleted ${what} (${r.deleted} samples)`);
      await loadSoil();
    } catch (e) {
      setSoilError(e);
    }
  };

  type SampleKey = keyof Schemas['SampleProps'];
  const sampleKeys = soil?.features[0]
    ? (Object.keys(soil.features[0].properties) as SampleKey[]).filter((k) => !SKIP_KEYS.has(k))
    : [];
  const numericKeys = sampleKeys.filter((k) => soil!.features.some((f) => typeof f.properties[k] === 'number'));
  const key = colorKey && numericKeys.includes(colorKey as SampleKey) ? (colorKey as SampleKey) : (numericKeys.find((k) => /^n_|nitrogen/i.test(k)) ?? numericKeys[0] ?? '');
  const vals = key ? (soil?.features ?? []).map((f) => Number(f.properties[key])).filter(Number.isFinite) : [];
  const vLo = vals.length ? vals.reduce((a, b) => Math.min(a, b)) : 0;
  const vHi = vals.length ? vals.reduce((a, b) => Math.max(a, b)) : 1;
  const sBreaks = niceBreaks(vLo, vHi === vLo ? vLo + 1 : vHi, 5);
  const sColors = classColors(sBreaks.length - 1);
  const sExpr = key ? stepExpression(key, sBreaks, sColors) : '#8b4513';

  useEffect(() => {
    const map = mapRef.current;
    if (map?.getLayer('soil')) map.setPaintProperty('soil', 'circle-color', sExpr as never);
  }, [JSON.stringify(sExpr)]); // eslint-disable-line react-hooks/exhaustive-deps

  return (
    <div className="split">
      <aside className="panel">
        <p>
          <a href="#/fields">← Fields</a>
        </p>
        <h2 data-testid="field-title">{field?.properties.name ?? '…'}</h2>
        <ErrorBox error={error} />
        {field && (
          <Kv
            items={[
              ['Area', formatArea(field.properties.area_m2 ?? (field.properties.area_ha ?? NaN) * 10_000), 'field-area'],
              ['Crop', field.properties.crop ?? '–'],
              ['UTM', field.properties.utm_epsg ? `EPSG:${field.properties.utm_epsg}` : '–'],
            ]}
          />
        )}
        <div className="row">
          <button data-testid="edit-field" data-write="" onClick={() => navigate(`/fields/${fieldId}/edit`)}>
            Edit boundary
          </button>
          <button
            className="danger"
            data-testid="delete-field" data-write=""
            onClick={async () => {
              if (!confirm('Delete this field?')) return;
              try {
                await call(client.DELETE('/api/v1/fields/{field_id}', { params: { path: { field_id: fieldId } } }));
                navigate('/fields');
              } catch (e) {
                setError(e);
              }
            }}
          >
            Delete
          </button>
        </div>

        <h3>Soil samples</h3>
        <div className="row">
          <label className="button" data-write="">
            Upload CSV…
            <input
              data-testid="soil-file" data-write=""
              type="file"
              accept=".csv,.geojson,.json"
              hidden
              onChange={(e) => {
                const f = e.target.files?.[0];
                if (f) void uploadSoil(f);
                e.target.value = '';
              }}
            />
          </label>
          <label className="inline">
            <input type="checkbox" checked={skipBad} onChange={(e) => setSkipBad(e.target.checked)} /> skip bad rows
          </label>
          <label className="inline">
            <input
              data-testid="soil-include-outside"
              type="checkbox"
              checked={includeOutside}
              onChange={(e) => setIncludeOutside(e.target.checked)}
            />{' '}
            also store samples outside the field
          </label>
        </div>
        {soilMsg && (
          <p className="ok" data-testid="soil-result">
            {soilMsg}
          </p>
        )}
        <ErrorBox error={soilError} testid="soil-error" />
        {outside.length > 0 && (
          <div className="card warn" data-testid="soil-outside">
            {outside.length} row{outside.length === 1 ? '' : 's'} outside the field:
            <ul>
              {outside.slice(0, 20).map((o) => (
                <li key={o.row}>
                  row {o.row} ({o.sample_id}){o.distance_m != null ? `: ${Math.round(o.distance_m).toLocaleString()} m away` : ''}
                </li>
              ))}
            </ul>
          </div>
        )}
        {imports.length > 0 && (
          <table className="table" data-testid="soil-imports">
            <thead>
              <tr>
                <th>Import</th>
                <th>Samples</th>
                <th>Outside</th>
                <th />
              </tr>
            </thead>
            <tbody>
              {imports.map((i) => (
                <tr key={i.id} data-testid={`soil-import-${i.id}`}>
                  <td>
                    {i.filename || `#${i.id}`}{' '}
                    <span className="muted small">{i.created_at ? new Date(i.created_at).toLocaleString() : ''}</span>
                  </td>
                  <td>{i.n_stored}</td>
                  <td>{i.n_outside ? `${i.n_outside}${i.outside_stored ? ' (stored)' : ' (not stored)'}` : '–'}</td>
                  <td>
                    <button
                      className="danger"
                      data-write=""
                      data-testid={`soil-import-delete-${i.id}`}
                      onClick={() => void remove(
                          () =>
                            call(
                              client.DELETE('/api/v1/fields/{field_id}/soil-imports/{import_id}', {
                                params: { path: { field_id: fieldId, import_id: i.id } },
                              }),
                            ),
                          `import ${i.filename || i.id}`,
                        )}
                    >
                      Delete
                    </button>
                  </td>
                </tr>
              ))}
            </tbody>
          </table>
        )}
        <p className="muted" data-testid="soil-count">
          {soil?.features.length ?? 0} samples
        </p>
        {key && (
          <>
            <label className="inline">
              Colour by{' '}
              <select data-testid="soil-color-key" value={key} onChange={(e) => setColorKey(e.target.value)}>
                {numericKeys.map((k) => (
                  <option key={k} value={k}>
                    {k}
                  </option>
                ))}
              </select>
            </label>
            <Legend entries={legendEntries(sBreaks, sColors, (v) => String(Math.round(v * 100) / 100))} title={key} testid="soil-legend" />
          </>
        )}
        {soil && soil.features.length > 0 && (
          <div className="scroll">
            <table className="table" data-testid="soil-table">
              <thead>
                <tr>
                  {sampleKeys.map((k) => (
                    <th key={k}>{k}</th>
                  ))}
                  <th />
                </tr>
              </thead>
              <tbody>
                {soil.features.slice(0, 200).map((f, i) => (
                  <tr key={i}>
                    {sampleKeys.map((k) => (
                      <td key={k}>{fmtCell(f.properties[k])}</td>
                    ))}
                    <td>
                      <button
                        className="small"
                        data-write=""
                        data-testid={`soil-sample-delete-${String(f.properties?.id)}`}
                        title="Delete this sample"
                        onClick={() =>
                          void remove(
                            () =>
                              call(
                                client.DELETE('/api/v1/fields/{field_id}/soil-samples/{sample_pk}', {
                                  params: { path: { field_id: fieldId, sample_pk: f.properties.id } },
                                }),
                              ),
                            `sample ${f.properties.sample_id}`,
                          )
                        }
                      >
                        ×
                      </button>
                    </td>
                  </tr>
                ))}
              </tbody>
            </table>
          </div>
        )}

        <h3>Plans</h3>
        {
          <>
            <ul className="list" data-testid="plan-list">
              {plans.map((p) => (
                <li key={p.id}>
                  <a href={`#/plans/${p.id}`} data-testid={`plan-item-${p.id}`}>
                    Plan #{p.id}
                  </a>{' '}
                  <span className="muted">
                    {p.params.swath_width_m} m swath · {p.params.cell_length_m} m cells
                  </span>
                </li>
              ))}
            </ul>
            <PlanForm fieldId={fieldId} onCreated={(p) => navigate(`/plans/${p.id}`)} />
          </>
        }
      </aside>
      <MapView name="field" onReady={onReady} fieldId={fieldId} />
    </div>
  );
}

function fmtCell(v: unknown): string {
  if (typeof v === 'number') return Number.isInteger(v) ? String(v) : v.toFixed(2);
  return v == null ? '' : String(v);
}
