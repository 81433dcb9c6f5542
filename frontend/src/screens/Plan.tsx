import { useEffect, useRef, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { api } from '../api';
import { ErrorBox, isMissingEndpoint, Kv } from '../components/Status';
import { bboxOf } from '../lib/geo';
import { formatDistance, formatPercent } from '../lib/units';
import { ImageryRxForm } from '../components/ImageryRxForm';
import { SoilZonesForm } from '../components/SoilZonesForm';
import { MapView } from '../map/MapView';
import { addRouteLayers, planGridLayers, planTilesUrl, replaceVectorSource } from '../map/grid';
import { fitTo, setGeoJSON } from '../map/setup';
import { attentionOf, attentionSummary } from '../lib/flags';
import { navigate } from '../router';
import type { FieldFeature, Plan, Prescription } from '../types';
import { listOf, pick } from '../types';
import { RxForm } from './RxForm';

/** A coverage plan: grid (vector tiles), path with direction arrows, stats; build prescriptions. */
export function PlanScreen({ planId }: { planId: number }) {
  const [plan, setPlan] = useState<Plan | null>(null);
  const [route, setRoute] = useState<GeoJSON.GeoJSON | null>(null);
  const [field, setField] = useState<FieldFeature | null>(null);
  const [rxs, setRxs] = useState<Prescription[]>([]);
  const [error, setError] = useState<unknown>(null);
  const mapRef = useRef<maplibregl.Map | null>(null);

  useEffect(() => {
    api
      .get<Plan>(`/plans/${planId}`)
      .then((p) => {
        setPlan(p);
        api.get<FieldFeature>(`/fields/${p.field_id}`).then(setField).catch(() => undefined);
      })
      .catch(setError);
    api.get<GeoJSON.GeoJSON>(`/plans/${planId}/route`).then(setRoute).catch(() => undefined);
    api
      .get(`/plans/${planId}/prescriptions`)
      .then((r) => setRxs(listOf<Prescription>(r)))
      .catch((e) => (isMissingEndpoint(e) ? undefined : setError(e)));
  }, [planId]);

  const [mapReady, setMapReady] = useState(false);
  useEffect(() => {
    const map = mapRef.current;
    if (!map) return;
    if (field) {
      setGeoJSON(map, 'field', field as GeoJSON.Feature);
      fitTo(map, bboxOf(field));
      // Grid tiles only once the view is on the field (no wasted low-zoom requests).
      if (!map.getSource('grid')) {
        replaceVectorSource(map, 'grid', planTilesUrl(planId), planGridLayers('grid'));
        if (map.getLayer('route-line')) map.moveLayer('route-line');
        if (map.getLayer('route-arrows')) map.moveLayer('route-arrows');
      }
    }
    if (route) setGeoJSON(map, 'route', route);
  }, [field, route, mapReady, planId]);

  const onReady = (map: maplibregl.Map) => {
    mapRef.current = map;
    setGeoJSON(map, 'field', (field as GeoJSON.Feature) ?? { type: 'FeatureCollection', features: [] });
    map.addLayer({ id: 'field-line', type: 'line', source: 'field', paint: { 'line-color': '#2d5e16', 'line-width': 2 } });
    setGeoJSON(map, 'route', route ?? { type: 'FeatureCollection', features: [] });
    addRouteLayers(map, 'route');
    setMapReady(true);
  };

  const s = {
    ...(plan ?? {}),
    ...((plan?.metrics as Record<string, unknown>) ?? {}),
    ...((plan?.stats as Record<string, unknown>) ?? {}),
  } as Record<string, unknown>;
  const coverage = pick(s, 'coverage', 'coverage_fraction', 'coverage_ratio');
  const coveragePct = pick(s, 'coverage_pct', 'coverage_percent');
  return (
    <div className="split">
      <aside className="panel">
        <p>{plan && <a href={`#/fields/${plan.field_id}`}>← {field?.properties.name ?? 'Field'}</a>}</p>
        <h2>Plan #{planId}</h2>
        <ErrorBox error={error} />
        {plan && (
          <Kv
            items={[
              ['Swath width', `${plan.swath_width_m ?? '–'} m`],
              ['Cell length', `${plan.cell_length_m ?? '–'} m`],
              ['Heading rule', `${plan.heading_rule ?? '–'}${plan.heading_deg != null ? ` (${Number(plan.heading_deg).toFixed(1)}°)` : ''}`],
              ['Headland passes', String(plan.headland_passes ?? '–')],
              ['Swaths', String(pick(s, 'swath_count', 'swaths', 'n_swaths') ?? '–'), 'plan-swaths'],
              ['Turns', String(pick(s, 'turn_count', 'turns', 'n_turns') ?? '–'), 'plan-turns'],
              [
                'Coverage',
                coverage != null ? formatPercent(coverage > 1 ? coverage / 100 : coverage) : coveragePct != null ? formatPercent(coveragePct / 100) : '–',
                'plan-coverage',
              ],
              ['Cells', String(pick(s, 'cell_count', 'cells', 'n_cells') ?? '–'), 'plan-cells'],
              ['Working length', formatDistance(pick(s, 'working_length_m', 'path_length_m')), 'plan-length'],
              ['Turns / transit', formatDistance(pick(s, 'nonworking_length_m'))],
              ['Overlap', pick(s, 'overlap_pct') != null ? formatPercent(pick(s, 'overlap_pct')! / 100) : '–'],
            ]}
          />
        )}
        <button
          className="danger"
          onClick={async () => {
            if (!confirm('Delete this plan?')) return;
            try {
              await api.del(`/plans/${planId}`);
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
