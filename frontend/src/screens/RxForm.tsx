import { useEffect, useState } from 'react';
import { call, client, type Machine, type Prescription, type Schemas, inline } from '../api/client';
import { ErrorBox } from '../components/Status';
import { serverDefault } from '../api/defaults';

/** Defaults from seed 002 eq. 19-21 (winter rape worked example, SCIENCE.md). */
export const MODEL_DEFAULTS: Record<string, Record<string, unknown>> = {
  nutrient_balance: {
    target_yield_kg_ha: 2500,
    e_kg_per_100kg: 5.8,
    k_utilisation: 0.342,
    n_fraction: 0.25,
  },
  uniform: { rate_kg_ha: 300 },
  ndvi: { ndvi_low: 0.2, rate_at_low_kg_ha: 400, ndvi_high: 0.8, rate_at_high_kg_ha: 150 },
};

export function RxForm({ planId, onCreated }: { planId: number; onCreated: (r: Prescription) => void }) {
  const [model, setModel] = useState('nutrient_balance');
  const [params, setParams] = useState(JSON.stringify(MODEL_DEFAULTS.nutrient_balance, null, 2));
  const [interp, setInterp] = useState<string>(serverDefault('PrescriptionIn', 'interpolation'));
  const [machines, setMachines] = useState<Machine[]>([]);
  const [machineId, setMachineId] = useState('');
  useEffect(() => {
    call(client.GET('/api/v1/machines'))
      .then((r) => {
        const ms = r.items;
        setMachines(ms);
        if (ms[0]) setMachineId(String(ms[0].id));
      })
      .catch(() => undefined);
  }, []);
  const [error, setError] = useState<unknown>(null);
  const [busy, setBusy] = useState(false);
  return (
    <form
      className="form"
      data-testid="rx-form" data-write=""
      onSubmit={async (e) => {
        e.preventDefault();
        setError(null);
        let p: Record<string, unknown>;
        try {
          p = JSON.parse(params);
        } catch {
          setError(new Error('Parameters must be JSON'));
          return;
        }
        setBusy(true);
        try {
          onCreated(
            inline(
              await call(
              client.POST('/api/v1/plans/{plan_id}/prescriptions', {
                params: { path: { plan_id: planId } },
                body: {
                  model,
                  params: p,
                  interpolation: interp as Schemas['PrescriptionIn']['interpolation'],
                  machine_id: machineId ? Number(machineId) : undefined,
                },
              }),
            ),
            ),
          );
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
          <option value="uniform">Uniform rate</option>
          <option value="ndvi">NDVI (linear)</option>
        </select>
      </label>
      <label>
        Interpolation
        <select data-testid="rx-interp" value={interp} onChange={(e) => setInterp(e.target.value)}>
          <option value="idw">Inverse distance</option>
          <option value="kriging">Kriging</option>
          <option value="cell_mean">Mean of samples in the cell</option>
        </select>
      </label>
      <label>
        Meter limits from
        <select data-testid="rx-machine" value={machineId} onChange={(e) => setMachineId(e.target.value)}>
          <option value="">— (no meter check)</option>
          {machines.map((m) => (
            <option key={m.id} value={m.id}>
              {m.name}
            </option>
          ))}
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
