import { useState } from 'react';
import { call, client, type Job, type Machine, type Schemas } from '../api/client';
import { qk, useInvalidate, useJobKinds, useJobs, usePrescription, useSendableMachines } from '../api/hooks';
import { ErrorBox } from '../components/Status';
import { jobBody, kindLabel, kindList, kindsTaking, unitRefusal } from '../lib/jobkinds';
import { jobLive, withLive, type JobLive } from '../lib/livejobs';
import { useLive } from '../live';
import { formatPercent } from '../lib/units';
import { hashQuery } from '../router';
import { SensorJobForm } from './SensorJobForm';

/** What a user may do from each state (server: fleet/jobstate.TRANSITIONS). */
const NEXT_STATES: Record<string, Schemas['StateIn']['state'][]> = {
  planned: ['sent', 'aborted'],
  sent: ['aborted'],
  downloaded: ['aborted'],
  running: ['paused', 'completed', 'aborted'],
  paused: ['running', 'completed', 'aborted'],
};
const ACTION: Record<string, string> = {
  sent: 'send',
  running: 'resume',
  paused: 'pause',
  completed: 'complete',
  aborted: 'abort',
};

/** "2026-05-04 07:12" (local time), or a dash. */
function when(iso: string | null | undefined): string {
  if (!iso) return '–';
  const d = new Date(iso);
  const p = (n: number) => String(n).padStart(2, '0');
  return `${d.getFullYear()}-${p(d.getMonth() + 1)}-${p(d.getDate())} ${p(d.getHours())}:${p(d.getMinutes())}`;
}

/** Jobs with product, field, machine, when they ran and their states; send a prescription
 * version to a machine. */
export function JobsScreen() {
  const jobsQ = useJobs({}, { refetchInterval: 5000 });
  // a machine added a moment ago (here, in another tab or over the API) is offered at once
  // (only those a job can be sent to: not the ones imports made to hold logs)
  const machinesQ = useSendableMachines({ staleTime: 0 });
  const refresh = useInvalidate();
  // between polls the live feed's job messages keep states and progress current
  const [live, setLive] = useState<ReadonlyMap<number, JobLive>>(new Map());
  useLive((msg) => {
    const got = jobLive(msg);
    if (!got) return;
    setLive((cur) => new Map(cur).set(got[0], got[1]));
    // a new state changes more than the row shows (started / ended): ask for the list at once
    const known = jobsQ.data?.items.find((j) => j.id === got[0]);
    if (!known || (got[1].state != null && got[1].state !== known.state)) void refresh(qk.jobs());
  });
  const jobs: Job[] = withLive(jobsQ.data?.items ?? [], live, jobsQ.dataUpdatedAt);
  const machines: Machine[] = machinesQ.data?.items ?? [];
  const [rxId, setRxId] = useState('');
  const [version, setVersion] = useState('');
  const [chosenMachine, setMachineId] = useState('');
  const kindsQ = useJobKinds();
  const kinds = kindsQ.data?.kinds;
  const [chosenKind, setKind] = useState('');
  // the registry's first kind until the user picks one
  const kindInfo = kinds?.[chosenKind] ?? kindList(kinds)[0];
  const kind = kindInfo?.name ?? '';
  const [actionError, setError] = useState<unknown>(null);
  const error = actionError ?? jobsQ.error;
  const created = hashQuery().get('created');
  // the first machine until the user picks one
  const machineId = chosenMachine || (machines[0] ? String(machines[0].id) : '');
  // the prescription typed in: a kind whose job does not take its rate unit is refused here
  const rxNum = /^\d+$/.test(rxId.trim()) ? Number(rxId) : null;
  const rxUnit = usePrescription(rxNum, { enabled: kindInfo?.rates_from === 'cells' }).data?.rate_unit;
  const refusal = kindInfo && rxUnit && rxNum != null ? unitRefusal(kindInfo, rxNum, rxUnit) : null;
  const taking = rxUnit ? kindsTaking(kinds, rxUnit) : [];
  const load = () => refresh(qk.jobs());

  const mName = (id: number) => machines.find((m) => m.id === id)?.name ?? `#${id}`;
  return (
    <div className="page">
      <h2>Jobs</h2>
      {created && (
        <p className="ok" data-testid="job-created">
          Job #{created} sent.
        </p>
      )}
      <ErrorBox error={error} testid="jobs-error" />
      <label>
        Kind{' '}
        <select data-testid="job-kind" value={kind} onChange={(e) => setKind(e.target.value)}>
          {kindList(kinds).map((k) => (
            <option key={k.name} value={k.name}>
              {k.label}
            </option>
          ))}
        </select>
      </label>
      {kindInfo?.rates_from === 'sensors' && (
        <SensorJobForm
          key={kind}
          kind={kindInfo}
          machines={machines}
          onError={setError}
          onCreated={() => void load()}
        />
      )}
      {kindInfo?.rates_from === 'cells' && <form
        className="row"
        data-testid="job-form" data-write=""
        onSubmit={async (e) => {
          e.preventDefault();
          setError(null);
          try {
            const body = jobBody(kindInfo, { prescriptionId: rxId, version, machineId });
            const j = await call(client.POST('/api/v1/jobs', { body }));
            if (j.state === 'planned')
              await call(
                client.POST('/api/v1/jobs/{job_id}/state', { params: { path: { job_id: j.id } }, body: { state: 'sent' } }),
              );
            await load();
          } catch (err) {
            setError(err);
          }
        }}
      >
        <input data-testid="job-rx" placeholder="Prescription #" value={rxId} onChange={(e) => setRxId(e.target.value)} required />
        <input data-testid="job-version" placeholder="version (latest)" value={version} onChange={(e) => setVersion(e.target.value)} />
        <select data-testid="job-form-machine" value={machineId} onChange={(e) => setMachineId(e.target.value)}>
          {machines.map((m) => (
            <option key={m.id} value={m.id}>
              {m.name}
            </option>
          ))}
        </select>
        <button data-testid="job-form-submit" disabled={!!refusal}>
          Send
        </button>
        {refusal && (
          <p className="warn" data-testid="job-kind-unit">
            {refusal}
            {taking.length ? ` (choose ${taking.map((k) => k.label).join(' or ')})` : ' (no job kind takes it)'}
          </p>
        )}
      </form>}
      <table className="table" data-testid="job-table">
        <thead>
          <tr>
            <th>Job</th>
            <th>Prescription / kind</th>
            <th>Product</th>
            <th>Field</th>
            <th>Machine</th>
            <th>Started</th>
            <th>Ended</th>
            <th>State</th>
            <th>Progress</th>
            <th>Flagged cells</th>
            <th />
          </tr>
        </thead>
        <tbody>
          {jobs.map((j) => (
            <tr key={j.id} data-testid={`job-row-${j.id}`}>
              <td>
                <a href={`#/jobs/${j.id}`}>#{j.id}</a>
              </td>
              <td data-testid={`job-source-${j.id}`}>
                {j.kind && kinds?.[j.kind]?.rates_from === 'sensors' ? (
                  <a href={`#/plans/${String(j.plan_id)}`}>{kindLabel(kinds, j.kind)}</a>
                ) : (
                  <a href={`#/prescriptions/${j.prescription_id}`}>
                    #{j.prescription_id} v{j.prescription_version ?? '?'}
                  </a>
                )}
              </td>
              <td data-testid={`job-product-${j.id}`}>{j.product || '–'}</td>
              <td data-testid={`job-field-${j.id}`}>
                {j.field_id != null ? <a href={`#/fields/${j.field_id}`}>{j.field_name ?? `#${j.field_id}`}</a> : '–'}
              </td>
              <td data-testid={`job-machine-${j.id}`}>
                <a href={`#/machines/${j.machine_id}`}>{j.machine_name ?? mName(j.machine_id)}</a>
              </td>
              <td data-testid={`job-started-${j.id}`}>{when(j.started_at)}</td>
              <td data-testid={`job-ended-${j.id}`}>{when(j.ended_at)}</td>
              <td>
                <span className={`state state-${j.state}`} data-testid={`job-state-${j.id}`}>
                  {j.state}
                </span>
              </td>
              <td data-testid={`job-progress-${j.id}`}>{j.progress != null ? formatPercent(j.progress > 1 ? j.progress / 100 : j.progress) : '–'}</td>
              <td data-testid={`job-flagged-${j.id}`} className={j.flagged_cells ? 'warn' : undefined}>
                {j.flagged_cells ? `${String(j.flagged_cells)}${j.flagged_confirmed ? ' (sent on confirmation)' : ''}` : '–'}
              </td>
              <td>
                {(NEXT_STATES[j.state] ?? []).map((s) => (
                  <button
                    key={s}
                    className="link"
                    data-testid={`job-${j.id}-${s}`} data-write=""
                    onClick={async () => {
                      try {
                        await call(
                          client.POST('/api/v1/jobs/{job_id}/state', { params: { path: { job_id: j.id } }, body: { state: s } }),
                        );
                        await load();
                      } catch (e) {
                        setError(e);
                      }
                    }}
                  >
                    {ACTION[s] ?? s}
                  </button>
                ))}{' '}
                <a href={`#/jobs/${j.id}`}>report</a>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
    </div>
  );
}
