import { useState } from 'react';
import { api } from '../api';
import { ErrorBox } from '../components/Status';
import type { Prescription } from '../types';

/** Defaults from seed 002 eq. 19-21 (winter rape worked example, SCIENCE.md). */
export const MODEL_DEFAULTS: Record<string, Record<string, unknown>> = {
  nutrient_balance: {
    target_yield_kg_ha: 2500,
    uptake_kg_per_100kg: 5.8,
    utilisation: 0.342,
    nutrient_fraction: 0.25,
    nutrient: 'n_mg_kg',
  },
  constant: { rate_kg_ha: 300 },
  ndvi_linear: { rate_at_ndvi0_kg_ha: 400, rate_at_ndvi1_kg_ha: 150 },
};

export function RxForm({ planId, onCreated }: { planId: number; onCreated: (r: Prescription) => void }) {
  const [model, setModel] = useState('nutrient_balance');
  const [params, setParams] = useState(JSON.stringify(MODEL_DEFAULTS.nutrient_balance, null, 2));
  const [interp, setInterp] = useState('idw');
  const [error, setError] = useState<unknown>(null);
  const [busy, setBusy] = useState(false);
  return (
    <form
      className="form"
      data-testid="rx-form"
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
          onCreated(await api.post<Prescription>(`/plans/${planId}/prescriptions`, { model, params: p, interpolation: interp }));
        } catch (err) {
          setError(err);
        } finally {
          setBusy(false);
        }
      }}
    >
      <h4>New prescription</h4>
      <label>
        Model
        <select
          data-testid="rx-model"
          value={model}
          onChange={(e) => {
            setModel(e.target.value);
            setParams(JSON.stringify(MODEL_DEFAULTS[e.target.value] ?? {}, null, 2));
          }}
        >
          <option value="nutrient_balance">Nutrient balance (soil N)</option>
          <option value="constant">Constant rate</option>
          <option value="ndvi_linear">NDVI linear</option>
        </select>
      </label>
      <label>
        Interpolation
        <select data-testid="rx-interp" value={interp} onChange={(e) => setInterp(e.target.value)}>
          <option value="idw">Inverse distance</option>
          <option value="kriging">Kriging</option>
          <option value="nearest">Nearest sample</option>
        </select>
      </label>
      <label>
        Parameters
        <textarea data-testid="rx-params" rows={7} value={params} onChange={(e) => setParams(e.target.value)} />
      </label>
      <button data-testid="rx-submit" disabled={busy}>
        {busy ? 'Computing…' : 'Build prescription'}
      </button>
      <ErrorBox error={error} testid="rx-error" />
    </form>
  );
}
