/** The machine screen's two write actions, each with its own state, progress and errors. */
import { useState } from 'react';
import { call, client, type Machine } from '../api/client';
import { formOf, validateCalibration, type CalibrationErrors, type CalibrationForm } from '../lib/calibration';
import { Busy, useBusy } from './Busy';
import { ErrorBox, FieldError } from './Status';

const FIELDS: [keyof CalibrationForm, string][] = [
  ['slope', 'a (g/min per r/min)'],
  ['intercept', 'b (g/min)'],
  ['minRpm', 'min r/min'],
  ['maxRpm', 'max r/min'],
  ['lag', 'lag s'],
];

/** Edit a linear calibration (seed 001 eq. 1); each check's message sits under its input. */
export function CalibrationEditor(props: { machine: Machine | null; onSaved: (m: Machine) => void }) {
  const { machine, onSaved } = props;
  const [form, setForm] = useState<CalibrationForm | null>(null);
  const [errors, setErrors] = useState<CalibrationErrors>({});
  const [error, setError] = useState<unknown>(null);
  const { busy, run } = useBusy();
  if (!machine) return null;
  if (!form)
    return machine.calibration?.kind !== 'table' ? (
      <button data-write="" data-testid="cal-edit" onClick={() => setForm(formOf(machine.calibration, machine.lag_s))}>
        Edit calibration
      </button>
    ) : null;
  return (
    <form
      className="card"
      data-testid="cal-edit-form"
      noValidate
      onSubmit={async (e) => {
        e.preventDefault();
        setError(null);
        const r = validateCalibration(form);
        setErrors(r.errors);
        if (!r.value) return;
        try {
          const body = r.value;
          onSaved(await run(() => call(client.PATCH('/api/v1/machines/{machine_id}', { params: { path: { machine_id: machine.id } }, body }))));
          setForm(null);
        } catch (err) {
          setError(err);
        }
      }}
    >
      <div className="row wrap">
        {FIELDS.map(([k, label]) => (
          <label className="inline cal-field" key={k}>
            {label}{' '}
            <input
              type="number"
              step="any"
              name={k}
              value={form[k]}
              aria-invalid={errors[k] ? true : undefined}
              aria-describedby={errors[k] ? `cal-${k}` : undefined}
              onChange={(e) => setForm({ ...form, [k]: e.target.value })}
            />
            <FieldError id={`cal-${k}`} message={errors[k]} />
          </label>
        ))}
      </div>
      <div className="row">
        <button data-write="" disabled={busy}>
          Save calibration
        </button>
        <button type="button" className="secondary" onClick={() => setForm(null)}>
          Cancel
        </button>
        <Busy busy={busy} label="saving…" />
      </div>
      <ErrorBox error={error} testid="cal-error" />
    </form>
  );
}

/** A new device token, shown once. */
export function DeviceToken({ machineId }: { machineId: number }) {
  const [token, setToken] = useState('');
  const [error, setError] = useState<unknown>(null);
  const { busy, run } = useBusy();
  return (
    <>
      <div className="row wrap">
        <button
          data-testid="device-token"
          data-write=""
          disabled={busy}
          onClick={async () => {
            setError(null);
            try {
              const r = await run(() =>
                call(client.POST('/api/v1/machines/{machine_id}/device-token', { params: { path: { machine_id: machineId } } })),
              );
              setToken(r.token);
            } catch (e) {
              setError(e);
            }
          }}
        >
          New device token
        </button>
        <Busy busy={busy} />
        {token && (
          <code className="token" data-testid="device-token-value">
            {token}
          </code>
        )}
      </div>
      <ErrorBox error={error} testid="device-token-error" />
      {token && <p className="muted small">Shown once: copy it into the edge agent's configuration now.</p>}
    </>
  );
}
