import { useState } from 'react';
import { call, client } from '../api/client';
import { qk, useField, useFieldPlans, useInvalidate, useSoilSamples } from '../api/hooks';
import { Legend } from '../components/Legend';
import { SoilImportAssistant } from '../components/SoilImportAssistant';
import { SoilSamples } from '../components/SoilSamples';
import { ErrorBox, Kv } from '../components/Status';
import { legendEntries } from '../lib/colors';
import { bboxOf } from '../lib/geo';
import { samplePopup, soilColoring } from '../lib/soil';
import { formatArea } from '../lib/units';
import { MapView } from '../map/MapView';
import { FieldBoundary, FitBounds, Points } from '../map/overlays';
import { navigate } from '../router';
import { PlanForm } from './PlanForm';

/** One field: boundary, soil samples (lab import assistant, list, map), plans. */
export function FieldDetail({ fieldId }: { fieldId: number }) {
  const fieldQ = useField(fieldId);
  const plansQ = useFieldPlans(fieldId);
  const soilQ = useSoilSamples(fieldId);
  const [error, setError] = useState<unknown>(null);
  const [soilMsg, setSoilMsg] = useState('');
  const [colorKey, setColorKey] = useState('');
  const refresh = useInvalidate();
  const field = fieldQ.data ?? null;
  const plans = plansQ.data?.items ?? [];
  const soil = soilQ.data;
  const c = soilColoring(soil, colorKey);

  return (
    <div className="split">
      <aside className="panel">
        <p>
          <a href="#/fields">← Fields</a>
        </p>
        <h2 data-testid="field-title">{field?.properties.name ?? '…'}</h2>
        <ErrorBox error={error ?? fieldQ.error ?? plansQ.error} />
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
            data-testid="delete-field"
            data-write=""
            onClick={async () => {
              if (!confirm('Delete this field?')) return;
              try {
                await call(client.DELETE('/api/v1/fields/{field_id}', { params: { path: { field_id: fieldId } } }));
                await refresh(qk.fields());
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
        <SoilImportAssistant
          fieldId={fieldId}
          onImported={(msg) => {
            setSoilMsg(msg);
            void refresh(qk.soilSamples(fieldId), qk.soilImports(fieldId));
          }}
        />
        {soilMsg && (
          <p className="ok" data-testid="soil-result">
            {soilMsg}
          </p>
        )}
        <ErrorBox error={soilQ.error} />
        <SoilSamples fieldId={fieldId} soil={soil} sampleKeys={c.sampleKeys} onMessage={setSoilMsg} />
        {c.key && (
          <>
            <label className="inline">
              Colour by{' '}
              <select data-testid="soil-color-key" value={c.key} onChange={(e) => setColorKey(e.target.value)}>
                {c.numericKeys.map((k) => (
                  <option key={k} value={k}>
                    {k}
                  </option>
                ))}
              </select>
            </label>
            <Legend entries={legendEntries(c.breaks, c.colors, (v) => String(Math.round(v * 100) / 100))} title={c.key} testid="soil-legend" />
          </>
        )}

        <h3>Plans</h3>
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
      </aside>
      <MapView name="field" fieldId={fieldId}>
        <FieldBoundary data={field} />
        <Points id="soil" data={soil} color={c.expr} popup={samplePopup} />
        <FitBounds bbox={field ? bboxOf(field) : null} />
      </MapView>
    </div>
  );
}
