import { useState } from 'react';
import { call, client, type Prescription, type Schemas } from '../api/client';
import { MODEL_DEFAULTS } from '../screens/RxForm';
import { ErrorBox } from './Status';
import { serverDefault } from '../api/defaults';

/**
 * Management zones from the field's soil samples (next to the imagery NDVI zones): the
 * model's input (soil N for nutrient balance, sample NDVI for the NDVI curve) interpolated
 * onto the plan's cells, k zones with the same classifier and minimum-area smoothing as
 * imagery zones, one model rate per zone (POST /plans/{id}/zones).
 */
export function SoilZonesForm(props: { planId: number; onCreated: (r: Prescription) => void }) {
  const { planId, onCreated } = props;
  const [model, setModel] = useState<'nutrient_balance' | 'ndvi'>('nutrient_balance');
  const [interp, setInterp] = useState<string>(serverDefault('SoilZonesIn', 'interpolation'));
  const [k, setK] = useState(serverDefault('SoilZonesIn', 'k'));
  const [minArea, setMinArea] = useState(0);
  const [params, setParams] = useState(JSON.stringify(MODEL_DEFAULTS.nutrient_balance, null, 2));
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<unknown>(null);
  return (
    <form
      className="form"
      data-testid="soil-zones-form"
      data-write=""
      onSubmit={async (e) => {
        e.preventDefault();
        setError(null);
        let p: unknown;
        try {
          p = JSON.parse(params);
        } catch {
          setError(new Error('Parameters must be JSON'));
          return;
        }
        setBusy(true);
        try {
          onCreated(
            await call(
              client.POST('/api/v1/plans/{plan_id}/zones', {
                params: { path: { plan_id: planId } },
                body: {
                  model,
                  params: p as Schemas['SoilZonesIn']['params'],
                  interpolation: interp as Schemas['SoilZonesIn']['interpolation'],
                  k,
                  min_area_m2: minArea,
                },
              }),
            ),
          );
        } catch (err) {
          setError(err);
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
          onChange={(e) => {
            const m = e.target.value as 'nutrient_balance' | 'ndvi';
            setModel(m);
            setParams(JSON.stringify(MODEL_DEFAULTS[m] ?? {}, null, 2));
          }}
        >
          <option value="nutrient_balance">Soil N (nutrient balance rate)</option>
          <option value="ndvi">Sample NDVI (NDVI rate)</option>
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
      <label>
        Rate model parameters
        <textarea data-testid="soil-zones-params" rows={5} value={params} onChange={(e) => setParams(e.target.value)} />
      </label>
      <button data-testid="soil-zones-submit" disabled={busy}>
        {busy ? 'Computing…' : 'Build soil zone prescription'}
      </button>
      <ErrorBox error={error} testid="soil-zones-error" />
    </form>
  );
}
