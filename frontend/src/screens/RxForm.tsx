import { useEffect, useRef, useState } from 'react';
import { call, client, type Machine, type Prescription, type Schemas, inline } from '../api/client';
import { RxModelFields } from '../components/RxModelFields';
import { ErrorBox } from '../components/Status';
import { RATE_MODELS } from '../lib/rateModels';
import { defaultFields, rxBody, type FieldErrors, type RxFields, type RxModel } from '../lib/rxform';
import { useCatalogue, usePlanFormDefaults } from '../lib/useCatalogue';
import { serverDefault } from '../api/defaults';

/** New prescription: crop-aware typed fields with units (no JSON), product from the catalogue, clamp, note. */
export function RxForm({ planId, onCreated }: { planId: number; onCreated: (r: Prescription) => void }) {
  const cat = useCatalogue();
  const start = usePlanFormDefaults(planId);
  const [model, setModel] = useState<RxModel>('nutrient_balance');
  const [fields, setFields] = useState<RxFields | null>(null);
  const [interp, setInterp] = useState<string>(serverDefault('PrescriptionIn', 'interpolation'));
  const [machines, setMachines] = useState<Machine[]>([]);
  const [machineId, setMachineId] = useState('');
  const [note, setNote] = useState('');
  const [err, setErr] = useState<{ api: unknown; fields: FieldErrors }>({ api: null, fields: {} });
  const [busy, setBusy] = useState(false);
  const formRef = useRef<HTMLFormElement>(null);
  useEffect(() => {
    call(client.GET('/api/v1/machines', { params: { query: { sendable: true } } }))
      .then((r) => {
        setMachines(r.items);
        if (r.items[0]) setMachineId(String(r.items[0].id));
      })
      .catch(() => undefined);
  }, []);
  useEffect(() => {
    if (!fields && cat.crops.length && start.ready) setFields(defaultFields(cat.crops, cat.products, start.data));
  }, [cat.crops, cat.products, fields, start.ready, start.data]);
  // An error is shown next to what caused it and scrolled into view.
  useEffect(() => {
    const el = formRef.current?.querySelector('[aria-invalid=true], [data-testid=rx-error]');
    el?.scrollIntoView({ block: 'center' });
  }, [err]);
  return (
    <form
      ref={formRef}
      className="form"
      data-testid="rx-form"
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
            inline(
              await call(
                client.POST('/api/v1/plans/{plan_id}/prescriptions', {
                  params: { path: { plan_id: planId } },
                  body: {
                    model: model as Schemas['PrescriptionIn']['model'],
                    ...body,
                    note,
                    interpolation: interp as Schemas['PrescriptionIn']['interpolation'],
                    machine_id: machineId ? Number(machineId) : undefined,
                  },
                }),
              ),
            ),
          );
        } catch (error) {
          setErr({ api: error, fields: {} });
        } finally {
          setBusy(false);
        }
      }}
    >
      <h4>New prescription</h4>
      <label>
        Model
        <select data-testid="rx-model" value={model} onChange={(e) => setModel(e.target.value as RxModel)}>
          {RATE_MODELS.map((m) => (
            <option key={m.name} value={m.name}>
              {m.label}
            </option>
          ))}
        </select>
      </label>
      {fields ? (
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
        />
      ) : (
        <p className="muted">Loading crops and products…</p>
      )}
      <ErrorBox error={cat.error} testid="rx-catalogue-error" />
      {model !== 'uniform' && (
        <label>
          Interpolation
          <select data-testid="rx-interp" value={interp} onChange={(e) => setInterp(e.target.value)}>
            <option value="idw">Inverse distance</option>
            <option value="kriging">Kriging</option>
            <option value="cell_mean">Mean of samples in the cell</option>
          </select>
        </label>
      )}
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
        Note (stored with version 1)
        <input data-testid="rx-note" value={note} maxLength={2000} onChange={(e) => setNote(e.target.value)} />
      </label>
      <button data-testid="rx-submit" disabled={busy || !fields}>
        {busy ? 'Computing…' : 'Build prescription'}
      </button>
      <ErrorBox error={err.api} testid="rx-error" />
    </form>
  );
}
