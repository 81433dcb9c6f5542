import { useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { call, client, type FieldFeature, type Plan, type Prescription, type Schemas } from '../api/client';
import { ErrorBox, Kv } from '../components/Status';
import { asGeoJSON, bboxOf } from '../lib/geo';
import { formatDistance, formatPercent } from '../lib/units';
import { ImageryRxForm } from '../components/ImageryRxForm';
import { SoilZonesForm } from '../components/SoilZonesForm';
import { MapView } from '../map/MapView';
import { addRouteLayers, planGridLayers, planTilesUrl, replaceVectorSource } from '../map/grid';
import { fitTo, setGeoJSON } from '../map/setup';
import { attentionOf, attentionSummary } from '../lib/flags';
import { navigate } from '../router';
import { RxForm } from './RxForm';

/** A coverage plan: grid (vector tiles), path with direction arrows, stats; build prescriptions. */
export function PlanScreen({ planId }: { planId: number }) {
  const [plan, setPlan] = useState<Plan | null>(null);
  const [route, setRoute] = useState<Schemas['RouteOut'] | null>(null);
  const [field, setField] = useState<FieldFeature | null>(null);
  const [rxs, setRxs] = useState<Prescription[]>([]);
  const [error, setError] = useState<unknown>(null);
  const mapRef = useRef<maplibregl.Map | null>(null);

  useEffect(() => {
    const path = { plan_id: planId };
    call(client.GET('/api/v1/plans/{plan_id}', { params: { path } }))
      .then((p) => {
        setPlan(p);
        call(client.GET('/api/v1/fields/{field_id}', { params: { path: { field_id: p.field_id } } }))
          .then(setField)
          .catch(() => undefined);
      })
      .catch(setError);
    call(client.GET('/api/v1/plans/{plan_id}/route', { params: { path } }))
      .then(setRoute)
      .catch(() => undefined);
    call(client.GET('/api/v1/plans/{plan_id}/prescriptions', { params: { path } }))
      .then((r) => setRxs(r.items))
      .catch(setError);
  }, [planId]);

  const [mapReady, setMapReady] = useState(false);
  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    if (field) {
      setGeoJSON(map, 'field', asGeoJSON(field));
      fitTo(map, bboxOf(field));
      // Grid tiles only once the view is on the field (no wasted low-zoom requests).
      if (!map.getSource('grid')) {
        replaceVectorSource(map, 'grid', planTilesUrl(planId), planGridLayers('grid'));
        if (map.getLayer('route-line')) map.moveLayer('route-line');
        if (map.getLayer('route-arrows')) map.moveLayer('route-arrows');
      }
    }
    if (route) setGeoJSON(map, 'route', asGeoJSON(route));
  }, [field, route, mapReady, planId]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'field', field ? asGeoJSON(field) : { type: 'FeatureCollection', features: [] });
    map.addLayer({ id: 'field-line', type: 'line', source: 'field', paint: { 'line-color': '#2d5e16', 'line-width': 2 } });
    setGeoJSON(map, 'route', route ? asGeoJSON(route) : { type: 'FeatureCollection', features: [] });
    addRouteLayers(map, 'route');
    setMapReady(true);
  };

  const m = plan?.metrics;
  return (
    <div className="split">
      <aside className="panel">
        <p>{plan && <a href={`#/fields/${plan.field_id}`}>← {field?.properties.name ?? 'Field'}</a>}</p>
        <h2>Plan #{planId}</h2>
        <ErrorBox error={error} />
        {plan && (
          <Kv
            items={[
              ['Swath width', `${plan.params.swath_width_m} m`],
              ['Cell length', `${plan.params.cell_length_m} m`],
              ['Heading rule', `${plan.params.heading}${plan.heading_deg != null ? ` (${plan.heading_deg.toFixed(1)}°)` : ''}`],
              ['Headland passes', String(plan.params.headland_passes ?? '–')],
              ['Swaths', String(m?.n_swaths ?? '–'), 'plan-swaths'],
              ['Turns', String(m?.n_turns ?? '–'), 'plan-turns'],
              ['Coverage', m?.coverage_pct != null ? formatPercent(m.coverage_pct / 100) : '–', 'plan-coverage'],
              ['Cells', String(plan.n_cells), 'plan-cells'],
              ['Working length', formatDistance(m?.working_length_m ?? undefined), 'plan-length'],
              ['Turns / transit', formatDistance(m?.nonworking_length_m ?? undefined)],
              ['Overlap', m?.overlap_pct != null ? formatPercent(m.overlap_pct / 100) : '–'],
            ]}
          />
        )}
        <button
          className="danger"
          onClick={async () => {
            if (!confirm('Delete this plan?')) return;
            try {
              await call(client.DELETE('/api/v1/plans/{plan_id}', { params: { path: { plan_id: planId } } }));
              navigate(plan ? `/fields/${plan.field_id}` : '/fields');
            } catch (e) {
              setError(e);
            }
          }}
        >
          Delete plan
        </button>
        <h3>Prescriptions</h3>
        <ul className="list" data-testid="rx-list">
          {rxs.map((r) => (
            <li key={r.id}>
              <a href={`#/prescriptions/${r.id}`}>
                #{r.id} {r.model}
              </a>
              {attentionOf(r).count > 0 && (
                <span className="warn small" data-testid={`rx-list-flagged-${r.id}`}>
                  {' '}
                  · {attentionSummary(attentionOf(r))} flagged
                </span>
              )}
            </li>
          ))}
        </ul>
        <RxForm planId={planId} onCreated={(r) => navigate(`/prescriptions/${r.id}`)} />
        {field?.id !== undefined && (
          <ImageryRxForm planId={planId} fieldId={field.id} onCreated={(r) => navigate(`/prescriptions/${r.id}`)} />
        )}
        <SoilZonesForm planId={planId} onCreated={(r) => navigate(`/prescriptions/${r.id}`)} />
      </aside>
      <MapView name="plan" onReady={onReady} fieldId={field?.id} />
    </div>
  );
}
