import { useEffect, useState } from 'react';
import { call, client, type Prescription, type Schemas } from '../api/client';
import { ZONE_MODELS } from '../lib/rateModels';
import { defaultFields, rxBody, type FieldErrors, type RxFields } from '../lib/rxform';
import { useCatalogue, usePlanFormDefaults } from '../lib/useCatalogue';
import { RxModelFields } from './RxModelFields';
import { ErrorBox } from './Status';
import { serverDefault } from '../api/defaults';

/**
 * Management zones from the field's soil samples (next to the imagery NDVI zones): the
 * model's input (soil N for nutrient balance, sample NDVI for the NDVI curve) interpolated
 * onto the plan's cells, k zones with the same classifier and minimum-area smoothing as
 * imagery zones, one model rate per zone (POST /plans/{id}/zones). The model's inputs are
 * the same typed fields as the prescription form's.
 */
export function SoilZonesForm(props: { planId: number; onCreated: (r: Prescription) => void }) {
  const { planId, onCreated } = props;
  const cat = useCatalogue();
  const start = usePlanFormDefaults(planId);
  const [model, setModel] = useState<'nutrient_balance' | 'ndvi'>('nutrient_balance');
  const [interp, setInterp] = useState<string>(serverDefault('SoilZonesIn', 'interpolation'));
  const [k, setK] = useState(serverDefault('SoilZonesIn', 'k'));
  const [minArea, setMinArea] = useState(0);
  const [fields, setFields] = useState<RxFields | null>(null);
  const [busy, setBusy] = useState(false);
  const [err, setErr] = useState<{ api: unknown; fields: FieldErrors }>({ api: null, fields: {} });
  useEffect(() => {
    if (!fields && cat.crops.length && start.ready) setFields(defaultFields(cat.crops, cat.products, start.data));
  }, [cat.crops, cat.products, fields, start.ready, start.data]);
  return (
    <form
      className="form"
      data-testid="soil-zones-form"
      data-write=""
      onSubmit={async (e) => {
        e.preventDefault();
        if (!fields) return;
        const { body, errors } = rxBody(model, fields);
        setErr({ api: null, fields: errors });
        if (!body) return;
        setBusy(true);
        try {
          onCreated(
            await call(
              client.POST('/api/v1/plans/{plan_id}/zones', {
                params: { path: { plan_id: planId } },
                body: {
                  model,
                  ...body,
                  interpolation: interp as Schemas['SoilZonesIn']['interpolation'],
                  k,
                  min_area_m2: minArea,
                },
              }),
            ),
          );
        } catch (error) {
          setErr({ api: error, fields: {} });
        } finally {
          setBusy(false);
        }
      }}
    >
      <h4>Zones from soil samples</h4>
      <label>
        Zone by
        <select
          data-testid="soil-zones-model"
          value={model}
          onChange={(e) => setModel(e.target.value as 'nutrient_balance' | 'ndvi')}
        >
          {ZONE_MODELS.map((m) => (
            <option key={m.name} value={m.name}>
              {m.zone_label}
            </option>
          ))}
        </select>
      </label>
      <label>
        Interpolation
        <select data-testid="soil-zones-interp" value={interp} onChange={(e) => setInterp(e.target.value)}>
          <option value="idw">Inverse distance</option>
          <option value="kriging">Kriging</option>
          <option value="cell_mean">Mean of samples in the cell</option>
        </select>
      </label>
      <div className="row wrap">
        <label>
          Zones
          <input data-testid="soil-zones-k" type="number" min={2} max={12} value={k} onChange={(e) => setK(Number(e.target.value))} />
        </label>
        <label>
          Min zone area (m²)
          <input data-testid="soil-zones-min-area" type="number" min={0} value={minArea} onChange={(e) => setMinArea(Number(e.target.value))} />
        </label>
      </div>
      {fields && (
        <RxModelFields
          model={model}
          fields={fields}
          setFields={(f) => {
            setFields(f);
            // an edited value is checked again on submit: its old error goes now
            if (Object.keys(err.fields).length) setErr({ api: err.api, fields: {} });
          }}
          errors={err.fields}
          crops={cat.crops}
          products={cat.products}
          onProductAdded={cat.reload}
          tid="soil-zones"
        />
      )}
      <button data-testid="soil-zones-submit" disabled={busy || !fields}>
        {busy ? 'Computing…' : 'Build soil zone prescription'}
      </button>
      <ErrorBox error={err.api} testid="soil-zones-error" />
    </form>
  );
}
