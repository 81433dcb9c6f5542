import { useState } from 'react';
import { ApiError, call, client, type Machine } from '../api/client';
import { useFieldPlans, useFields } from '../api/hooks';
import { flaggedConfirmation } from '../lib/flags';
import { kindUi } from '../kinds';
import { jobBody, planLabel, type KindInfo } from '../lib/jobkinds';

/**
 * The form of a sensor job kind (its rates decided on the go): the plan to drive (a field,
 * then one of its plans), the machine, and the kind's settings as GET /jobs/kinds lists
 * them, each with its unit and its default's source. Only changed values are sent; the
 * server fills in the rest and names any bad input. The kind's own note (src/kinds/) follows.
 */
export function SensorJobForm({
  kind,
  machines,
  onCreated,
  onError,
}: {
  kind: KindInfo;
  machines: Machine[];
  onCreated: (id: number) => void;
  onError: (e: unknown) => void;
}) {
  const [planId, setPlanId] = useState('');
  const [machineId, setMachineId] = useState(machines[0] ? String(machines[0].id) : '');
  const [values, setValues] = useState<Record<string, string>>({});
  const fields = kind.settings;
  const val = (p: string, paper: unknown) => values[p] ?? String(paper);
  const note = kindUi(kind.name).formNote;
  // a rate curve the machine cannot meter: the server's sentence, until the user confirms
  const [conflict, setConflict] = useState<string | null>(null);
  const send = async (confirmed: boolean) => {
    onError(null);
    try {
      const mid = machineId || (machines[0] ? String(machines[0].id) : '');
      const body = { ...jobBody(kind, { planId, machineId: mid }, values), confirm_flagged: confirmed };
      const j = await call(client.POST('/api/v1/jobs', { body }));
      setConflict(null);
      await call(client.POST('/api/v1/jobs/{job_id}/state', { params: { path: { job_id: j.id } }, body: { state: 'sent' } }));
      onCreated(j.id);
    } catch (err) {
      const c = err instanceof ApiError ? flaggedConfirmation(err.status, err.body) : null;
      if (c) setConflict(c.message);
      else onError(err);
    }
  };
  return (
    <form
      className="stack"
      data-testid={`job-form-${kind.name}`}
      data-write=""
      onSubmit={(e) => {
        e.preventDefault();
        void send(false);
      }}
    >
      <h3>{kind.label}</h3>
      <div className="row">
        <PlanPicker planId={planId} onPick={setPlanId} />
        <label>
          Machine{' '}
          <select data-testid="job-kind-machine" value={machineId} onChange={(e) => setMachineId(e.target.value)}>
            {machines.map((m) => (
              <option key={m.id} value={m.id}>
                {m.name}
              </option>
            ))}
          </select>
        </label>
      </div>
      <table className="table small">
        <tbody>
          {fields.map((f) => (
            <tr key={f.path}>
              <td>{f.label}</td>
              <td>
                {f.options.length ? (
                  <select
                    data-testid={`set-${f.path}`}
                    value={val(f.path, f.default)}
                    onChange={(e) => setValues({ ...values, [f.path]: e.target.value })}
                  >
                    {f.options.map((o) => (
                      <option key={o} value={o}>
                        {o}
                      </option>
                    ))}
                  </select>
                ) : (
                  <input
                    data-testid={`set-${f.path}`}
                    type="number"
                    step={f.step ?? 'any'}
                    value={val(f.path, f.default)}
                    onChange={(e) => setValues({ ...values, [f.path]: e.target.value })}
                  />
                )}{' '}
                {f.unit}
              </td>
              <td className="muted small">
                paper default: {String(f.default)} {f.unit} ({f.source})
              </td>
            </tr>
          ))}
        </tbody>
      </table>
      {note?.(values)}
      <button data-testid="job-kind-submit">Send</button>
      {conflict && (
        <div className="card warn" data-testid="job-kind-confirm-panel" role="alertdialog">
          <p data-testid="job-kind-confirm-text">{conflict}</p>
          <div className="row">
            <button type="button" data-testid="job-kind-confirm" className="danger" onClick={() => void send(true)}>
              Send anyway
            </button>
            <button type="button" data-testid="job-kind-confirm-cancel" onClick={() => setConflict(null)}>
              Cancel
            </button>
          </div>
        </div>
      )}
    </form>
  );
}

/** The plan to drive, picked by field then by one of its plans (newest first), not typed as a number. */
function PlanPicker({ planId, onPick }: { planId: string; onPick: (planId: string) => void }) {
  // read afresh whenever the form opens: a field or plan made a moment ago is offered
  const fieldsQ = useFields({ limit: 500 }, { staleTime: 0 });
  const [fieldId, setFieldId] = useState('');
  const plansQ = useFieldPlans(fieldId ? Number(fieldId) : null, { staleTime: 0 });
  const fields = fieldsQ.data?.features ?? [];
  const plans = [...(plansQ.data?.items ?? [])].sort((a, b) => b.id - a.id);
  return (
    <>
      <label>
        Field{' '}
        <select
          data-testid="job-field"
          value={fieldId}
          required
          onChange={(e) => {
            setFieldId(e.target.value);
            onPick('');
          }}
        >
          <option value="">{fieldsQ.isLoading ? 'loading…' : 'choose a field'}</option>
          {fields.map((f) => (
            <option key={f.properties.id} value={f.properties.id}>
              {f.properties.name}
            </option>
          ))}
        </select>
      </label>
      <label>
        Plan{' '}
        <select data-testid="job-plan" value={planId} required disabled={!fieldId} onChange={(e) => onPick(e.target.value)}>
          <option value="">{!fieldId ? 'choose a field first' : plansQ.isLoading ? 'loading…' : plans.length ? 'choose a plan' : 'no plan on this field'}</option>
          {plans.map((p) => (
            <option key={p.id} value={p.id}>
              {planLabel(p)}
            </option>
          ))}
        </select>
      </label>
    </>
  );
}
