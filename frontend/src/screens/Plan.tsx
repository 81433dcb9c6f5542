import { call, client } from '../api/client';
import { qk, useApiMutation, useField, useInvalidate, usePlan, usePlanPrescriptions, usePlanRoute } from '../api/hooks';
import { ErrorBox, Kv } from '../components/Status';
import { bboxOf } from '../lib/geo';
import { formatArea, formatDistance, formatPercent } from '../lib/units';
import { headingRuleName, modelName } from '../lib/words';
import { ImageryRxForm } from '../components/ImageryRxForm';
import { SoilZonesForm } from '../components/SoilZonesForm';
import { MapView } from '../map/MapView';
import { planTilesUrl } from '../map/grid';
import { CellGrid, FieldBoundary, FitBounds, Track } from '../map/overlays';
import { attentionOf, attentionSummary } from '../lib/flags';
import { navigate } from '../router';
import { RxForm } from './RxForm';

/** A coverage plan: grid (vector tiles), path with direction arrows, stats; build prescriptions. */
export function PlanScreen({ planId }: { planId: number }) {
  const planQ = usePlan(planId);
  const plan = planQ.data;
  const fieldQ = useField(plan?.field_id);
  const field = fieldQ.data;
  const route = usePlanRoute(planId).data;
  const rxsQ = usePlanPrescriptions(planId);
  const rxs = rxsQ.data?.items ?? [];
  const del = useApiMutation(() => call(client.DELETE('/api/v1/plans/{plan_id}', { params: { path: { plan_id: planId } } })), {
    invalidate: () => (plan ? [qk.fieldPlans(plan.field_id)] : []),
  });
  const error = planQ.error ?? rxsQ.error ?? del.error;
  const invalidate = useInvalidate();
  /** A new prescription: the plan's list is stale, then open it. */
  const created = (r: { id: number }) => {
    void invalidate(qk.planPrescriptions(planId));
    navigate(`/prescriptions/${r.id}`);
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
              ['Heading rule', `${headingRuleName(plan.params.heading)}${plan.heading_deg != null ? ` (${plan.heading_deg.toFixed(1)}°)` : ''}`],
              ['Headland passes', String(plan.params.headland_passes ?? '–')],
              ['Swaths', String(m?.n_swaths ?? '–'), 'plan-swaths'],
              ['Turns', String(m?.n_turns ?? '–'), 'plan-turns'],
              ['Coverage', m?.coverage_pct != null ? formatPercent(m.coverage_pct / 100) : '–', 'plan-coverage'],
              ['Cells', String(plan.n_cells), 'plan-cells'],
              ['Working length', formatDistance(m?.working_length_m ?? undefined), 'plan-length'],
              ['Turns / transit', formatDistance(m?.nonworking_length_m ?? undefined)],
              ['Overlap', m?.overlap_pct != null ? formatPercent(m.overlap_pct / 100) : '–'],
              ['Turning radius', plan.params.turn_radius_m != null ? `${plan.params.turn_radius_m} m` : '–'],
              ['Uncovered', formatArea(m?.uncovered_m2 ?? undefined), 'plan-uncovered'],
              // a part of the uncovered area (the plan's warning says so), not beside it
              ['… of which unworked corners', formatArea(m?.corner_loss_m2 ?? undefined), 'plan-corner-loss'],
            ]}
          />
        )}
        {!!m?.warnings?.length && (
          <ul className="warn small" data-testid="plan-warnings">
            {m.warnings.map((w) => (
              <li key={w}>{w}</li>
            ))}
          </ul>
        )}
        <button
          className="danger"
          onClick={() => {
            if (!confirm('Delete this plan?')) return;
            del.mutate(undefined, { onSuccess: () => navigate(plan ? `/fields/${plan.field_id}` : '/fields') });
          }}
        >
          Delete plan
        </button>
        <h3>Prescriptions</h3>
        <ul className="list" data-testid="rx-list">
          {rxs.map((r) => (
            <li key={r.id}>
              <a href={`#/prescriptions/${r.id}`}>
                #{r.id} {modelName(r.model)}
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
        <RxForm planId={planId} onCreated={created} />
        {field?.id !== undefined && (
          <ImageryRxForm planId={planId} fieldId={field.id} onCreated={created} />
        )}
        <SoilZonesForm planId={planId} onCreated={created} />
      </aside>
      <MapView name="plan" fieldId={field?.id}>
        {/* fit first: grid tiles only once the view is on the field (no wasted low-zoom requests) */}
        <FitBounds bbox={bboxOf(field)} />
        <FieldBoundary data={field} fill={false} />
        {field && <CellGrid id="grid" tiles={planTilesUrl(planId)} />}
        <Track id="route" data={route} arrows />
      </MapView>
    </div>
  );
}
